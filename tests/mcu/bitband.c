/* tests/mcu: the bit-band aliases (PM0214 2.2.5). SRAM: bits of a word set and cleared
 * through its alias, the alias read back as 0 or 1. Peripherals: RCC_CR's PLLON set
 * through its alias as ST's HAL does (the PLL locks), GPIOA's ODR bit 5 set alone through
 * its alias (the other bits kept), LSION through RCC_CSR's alias and LSIRDY read through
 * the alias of bit 1. Prints one line of hex words. Unwritten flash reads erased (0xFF). */
#include "board.h"

#define SRAM_BB(addr, bit) REG(0x22000000 + ((uint32_t)(addr) - 0x20000000) * 32 + 4 * (bit))
#define PERIPH_BB(addr, bit) REG(0x42000000 + ((addr) - 0x40000000) * 32 + 4 * (bit))
#define RCC_CSR_ADDR 0x40023874u

volatile uint32_t word = 0x80000001u;

int main(void) {
    SRAM_BB(&word, 4) = 1;                  /* 0x80000011 */
    SRAM_BB(&word, 31) = 0;                 /* 0x00000011 */
    uint32_t bit0 = SRAM_BB(&word, 0), bit1 = SRAM_BB(&word, 1);
    ((volatile uint8_t *)&word)[2] = 0;     /* a byte store beside it */
    SRAM_BB((uint32_t)&word + 2, 7) = 1;    /* bit 23 through the third byte's alias */
    FLASH_ACR = 3;
    RCC_PLLCFGR = 8 | (100 << 6) | (0 << 16) | (4 << 24);
    PERIPH_BB(0x40023800u, 24) = 1;         /* PLLON, as __HAL_RCC_PLL_ENABLE() */
    while (!PERIPH_BB(0x40023800u, 25)) {}  /* PLLRDY */
    RCC_CFGR = (4 << 10) | 2;
    while (((RCC_CFGR >> 2) & 3) != 2) {}
    console_init();
    GPIOA(0x14) = 0x3;                      /* ODR */
    PERIPH_BB(0x40020014u, 5) = 1;
    PERIPH_BB(RCC_CSR_ADDR, 0) = 1;          /* LSION */
    while (!PERIPH_BB(RCC_CSR_ADDR, 1)) {}   /* LSIRDY */
    uint32_t erased = REG(0x0807FFFC);       /* the last word of flash, no ELF section */
    put_word(word);
    put_word(bit0 | bit1 << 4);
    put_word(RCC_CR & (3u << 24));
    put_word(GPIOA(0x14));
    put_word(REG(RCC_CSR_ADDR) & 3);
    put_word(erased);
    console_puts("\n");
    for (;;) __asm__ volatile("wfi");
}
