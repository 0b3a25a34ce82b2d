/* tests/mcu: the FLASH interface (RM0383 3). Unlocked by the two keys, a word programmed
 * (bits only go from 1 to 0), sector 1 erased back to 0xFF with BSY up for the erase's
 * time, EOP and the FLASH interrupt with EOPIE, a store without PG refused (PGSERR, the
 * word unchanged), a byte store at PSIZE x32 refused (PGPERR), the flags cleared by
 * writing 1, a wrong key locking CR until reset. Prints one line of hex words. */
#include "board.h"

#define FLASH_KEYR REG(0x40023C04)
#define FLASH_SR REG(0x40023C0C)
#define FLASH_CR REG(0x40023C10)
#define BSY (1u << 16)
#define PG 1u
#define SER 2u
#define STRT (1u << 16)
#define EOPIE (1u << 24)
#define LOCK (1u << 31)
#define PSIZE_X32 (2u << 8)
#define WORD REG(0x08004000)

static volatile uint32_t eop_irqs;

void FLASH_IRQHandler(void) {
    FLASH_SR = 1;                             /* EOP: write 1 to clear */
    eop_irqs++;
}

static void program(uint32_t value) {
    FLASH_CR = PSIZE_X32 | PG;
    WORD = value;
    while (FLASH_SR & BSY) {}
    FLASH_CR = 0;
}

int main(void) {
    console_init();
    DEMCR |= 1u << 24;
    DWT_CTRL |= 1;
    uint32_t locked = FLASH_CR;
    FLASH_KEYR = 0x45670123u;
    FLASH_KEYR = 0xCDEF89ABu;
    uint32_t unlocked = FLASH_CR;
    program(0x12345678u);
    uint32_t first = WORD;
    program(0xFFFF0000u);                     /* 0x12340000: no bit goes back to 1 */
    uint32_t second = WORD;
    NVIC_ISER(0) = 1u << 4;                   /* FLASH global interrupt */
    FLASH_CR = PSIZE_X32 | SER | (1u << 3) | EOPIE;
    uint32_t t0 = DWT_CYCCNT;
    FLASH_CR |= STRT;
    uint32_t busy = FLASH_SR & BSY;
    while (FLASH_SR & BSY) {}
    uint32_t erase_ms = (DWT_CYCCNT - t0) / 16000u;   /* HSI 16 MHz */
    uint32_t erased = WORD;
    FLASH_CR = 0;
    WORD = 0;                                 /* no PG: PGSERR, nothing programmed */
    uint32_t pgserr = FLASH_SR;
    FLASH_SR = 0x80;
    FLASH_CR = PSIZE_X32 | PG;
    *(volatile uint8_t *)0x08004004 = 0;      /* a byte at x32: PGPERR */
    uint32_t pgperr = FLASH_SR;
    FLASH_SR = 0xF0;
    uint32_t cleared = FLASH_SR;
    FLASH_CR = LOCK;
    FLASH_KEYR = 0x12345678u;                 /* a wrong key: locked until reset */
    FLASH_KEYR = 0x45670123u;
    FLASH_KEYR = 0xCDEF89ABu;
    put_word(locked);
    put_word(unlocked);
    put_word(first);
    put_word(second);
    put_word(busy);
    put_word(erase_ms);
    put_word(erased);
    put_word(eop_irqs);
    put_word(pgserr);
    put_word(pgperr);
    put_word(cleared);
    put_word(REG(0x08004004));
    put_word(FLASH_CR & LOCK);
    console_puts("\n");
    for (;;) __asm__ volatile("wfi");
}
