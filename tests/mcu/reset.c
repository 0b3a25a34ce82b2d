/* tests/mcu: SCB AIRCR SYSRESETREQ reboots the board once. The first boot counts in a word
 * of SRAM no startup code touches (SRAM keeps its contents through a reset), sets the clock
 * to 100 MHz, turns SysTick and the console on, prints and asks for the reset; the second
 * boot prints what it finds: the counter, the reset state of RCC, SysTick and VTOR, and the
 * DWT cycle counter off again. */
#include "board.h"

#define BOOTS REG(0x20010000)            /* beyond .data/.bss, far below the stack */
#define MAGIC 0xB0070000u
#define SCB_VTOR REG(0xE000ED08)
#define SCB_AIRCR REG(0xE000ED0C)

static void put_hex(const char *label, uint32_t v) {
    char buf[12];
    console_puts(label);
    for (int i = 0; i < 8; i++)
        buf[i] = "0123456789abcdef"[(v >> (28 - 4 * i)) & 0xF];
    buf[8] = 0;
    console_puts(buf);
}

volatile uint32_t ticks;
void SysTick_Handler(void) { ticks++; }

int main(void) {
    uint32_t boots = (BOOTS & 0xFFFF0000u) == MAGIC ? (BOOTS & 0xFFFF) + 1 : 1;
    BOOTS = MAGIC | boots;
    uint32_t cfgr = RCC_CFGR, apb2 = RCC_APB2ENR, csr = SYST_CSR, vtor = SCB_VTOR;
    clock_100mhz();
    console_init();
    if (boots == 1) {
        DEMCR |= 1u << 24;
        DWT_CTRL |= 1;
        SYST_RVR = 100000 - 1;
        SYST_CVR = 0;
        SYST_CSR = 7;
        console_puts("boot 1: resetting\n");
        while (!(USART1(SR) & (1 << 6))) {}   /* TC: the line is out */
        SCB_AIRCR = (0x05FAu << 16) | (1u << 2);
        for (;;) {}
    }
    uint32_t cycles = DWT_CYCCNT;
    console_puts("boot ");
    put_hex("", boots);
    put_hex(" cfgr ", cfgr);
    put_hex(" apb2enr ", apb2);
    put_hex(" systick ", csr);
    put_hex(" vtor ", vtor);
    put_hex(" cyccnt ", cycles);
    console_puts("\n");
    for (;;) __asm volatile("wfi");
}
