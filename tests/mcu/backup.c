/* tests/mcu: the backup domain survives a system reset (RM0383 5.1.2, 17). Boot 1 starts
 * the RTC on LSE at 10:00:00, writes a backup register, sleeps 1.2 s and resets (AIRCR
 * SYSRESETREQ); boot 2 finds the register, BDCR's LSE and RTC bits and the calendar still
 * counting (10:00:01), prints them in one line of hex words, and sleeps. */
#include "board.h"

#define PWR_CR REG(0x40007000)
#define RCC_BDCR REG(0x40023870)
#define RTC(o) REG(0x40002800 + (o))
#define AIRCR REG(0xE000ED0C)
#define MAGIC 0xB0075AFEu

static volatile uint32_t ms;

void SysTick_Handler(void) { ms++; }

int main(void) {
    RCC_APB1ENR |= 1u << 28;                  /* PWR */
    if (RTC(0x50) != MAGIC) {
        PWR_CR |= 1u << 8;                    /* DBP */
        RCC_BDCR |= 1;                        /* LSEON */
        while (!(RCC_BDCR & 2)) {}
        RCC_BDCR |= (1u << 8) | (1u << 15);   /* RTCSEL = LSE, RTCEN */
        RTC(0x24) = 0xCA;
        RTC(0x24) = 0x53;
        RTC(0x0C) = 1u << 7;                  /* INIT */
        while (!(RTC(0x0C) & (1u << 6))) {}
        RTC(0x10) = 255;
        RTC(0x10) |= 127u << 16;              /* 32768 / 128 / 256 = 1 Hz */
        RTC(0x00) = 0x100000;                 /* 10:00:00 */
        RTC(0x0C) = 0;
        RTC(0x50) = MAGIC;
        SYST_RVR = 16000 - 1;                 /* 1 ms at HSI 16 MHz */
        SYST_CVR = 0;
        SYST_CSR = 7;
        while (ms < 1200) __asm__ volatile("wfi");
        AIRCR = 0x05FA0004;
        for (;;) {}
    }
    console_init();
    put_word(RTC(0x50));
    put_word(RCC_BDCR & 0x8303);
    put_word(RTC(0x00));
    console_puts("\n");
    for (;;) __asm__ volatile("wfi");
}
