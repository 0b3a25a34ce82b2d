/* tests/mcu: the window watchdog refreshed inside its window by polling its counter, five
 * times, then left alone: it resets the MCU, and the next boot finds RCC CSR's WWDGRSTF.
 * Each refresh prints the counter the poll saw: the first value below the window (0x5f),
 * as the counter falls one step at a time between the board's events. At the reset clock
 * (HSI 16 MHz, PCLK1 16 MHz: 256 us a step), refreshed to 0x61. */
#include "board.h"

#define WWDG_CR REG(0x40002C00)
#define WWDG_CFR REG(0x40002C04)
#define RCC_CSR REG(0x40023874)

int main(void) {
    uint32_t csr = RCC_CSR;
    console_init();
    USART1(BRR) = 139;                         /* 115200 baud at 16 MHz */
    if (csr & (1u << 30)) {
        console_puts("wwdg reset seen\n");
        for (;;) __asm volatile("wfi");
    }
    RCC_APB1ENR |= 1u << 11;
    WWDG_CFR = 0x60;                           /* window 0x60, PCLK1 / 4096 */
    WWDG_CR = 0x80 | 0x61;                     /* WDGA, T = 0x61 */
    for (int i = 0; i < 5; i++) {
        uint32_t t;
        while ((t = WWDG_CR & 0x7F) >= 0x60) {}
        WWDG_CR = 0x61;                        /* refreshed inside the window */
        char hex[4] = {"0123456789abcdef"[t >> 4], "0123456789abcdef"[t & 15], ' ', 0};
        console_puts(hex);
    }
    console_puts("refreshed\n");
    for (;;) __asm volatile("wfi");
}
