/* tests/mcu: the independent watchdog resets a firmware that stops refreshing it. Started
 * as ST's HAL_IWDG_Init does (start, unlock, PR and RLR, wait for SR, reload) with a 10 ms
 * timeout on LSI; the first boot then sleeps (or, with REFRESH, refreshes it each SysTick);
 * a boot after RCC CSR's IWDGRSTF says so and clears the flags (RMVF). */
#include "board.h"

#define IWDG_KR REG(0x40003000)
#define IWDG_PR REG(0x40003004)
#define IWDG_RLR REG(0x40003008)
#define IWDG_SR REG(0x4000300C)
#define RCC_CSR REG(0x40023874)

void SysTick_Handler(void) {
#ifdef REFRESH
    IWDG_KR = 0xAAAA;
#endif
}

int main(void) {
    uint32_t csr = RCC_CSR;
    clock_100mhz();
    console_init();
    if (csr & (1u << 29)) {
        RCC_CSR |= 1u << 24;                   /* RMVF */
        console_puts((RCC_CSR >> 29) & 1 ? "flag kept\n" : "iwdg reset seen\n");
        for (;;) __asm volatile("wfi");
    }
    RCC_CSR |= 1;                              /* LSION */
    while (!(RCC_CSR & 2)) {}
    IWDG_KR = 0xCCCC;
    IWDG_KR = 0x5555;
    IWDG_PR = 0;                               /* LSI / 4: 125 us a count */
    IWDG_RLR = 79;                             /* 80 counts: 10 ms */
    while (IWDG_SR) {}
    IWDG_KR = 0xAAAA;
    SYST_RVR = 100000 - 1;                     /* 1 ms at 100 MHz */
    SYST_CVR = 0;
    SYST_CSR = 7;
    console_puts("iwdg started\n");
    for (;;) __asm volatile("wfi");
}
