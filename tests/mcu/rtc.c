/* tests/mcu: the RTC on LSI (RM0383 17). PWR CR DBP opens the backup domain, LSI starts,
 * RTCSEL = LSI with RTCEN; WPR's key, INIT until INITF, PRER for 1 Hz (128 x 250), the
 * calendar set to 23:59:58 on 2026-12-31 (a Thursday); then two seconds asleep between
 * SysTicks and the calendar read back (00:00:00 on 2027-01-01, a Friday); a backup
 * register kept, one written without DBP dropped. Prints one line of hex words. */
#include "board.h"

#define PWR_CR REG(0x40007000)
#define RCC_BDCR REG(0x40023870)
#define RCC_CSR REG(0x40023874)
#define RTC(o) REG(0x40002800 + (o))
#define TR 0x00
#define DR 0x04
#define ISR 0x0C
#define PRER 0x10
#define WPR 0x24
#define BKP0R 0x50

static volatile uint32_t ms;

void SysTick_Handler(void) { ms++; }

int main(void) {
    console_init();
    RCC_APB1ENR |= 1u << 28;                  /* PWR */
    RTC(BKP0R) = 0x11;                        /* no DBP: dropped */
    PWR_CR |= 1u << 8;                        /* DBP */
    RCC_CSR |= 1;                             /* LSION */
    while (!(RCC_CSR & 2)) {}
    RCC_BDCR = (2u << 8) | (1u << 15);        /* RTCSEL = LSI, RTCEN */
    RTC(ISR) = 1u << 7;                       /* INIT while locked: ignored */
    uint32_t locked = RTC(ISR);
    RTC(WPR) = 0xCA;
    RTC(WPR) = 0x53;
    RTC(ISR) = 1u << 7;
    while (!(RTC(ISR) & (1u << 6))) {}        /* INITF */
    RTC(PRER) = 249;
    RTC(PRER) |= 127u << 16;
    RTC(TR) = 0x235958;
    RTC(DR) = 0x26 << 16 | 4u << 13 | 0x12 << 8 | 0x31;
    RTC(ISR) = 0;                             /* leave INIT */
    SYST_RVR = 16000 - 1;                     /* 1 ms at HSI 16 MHz */
    SYST_CVR = 0;
    SYST_CSR = 7;
    while (ms < 2000) __asm__ volatile("wfi");
    RTC(ISR) &= ~(1u << 5);                   /* clear RSF, wait for the shadow copy */
    uint32_t rsf_cleared = RTC(ISR) & (1u << 5);
    while (!(RTC(ISR) & (1u << 5))) {}
    RTC(WPR) = 0xFF;                          /* locked again */
    uint32_t tr = RTC(TR), dr = RTC(DR);
    RTC(BKP0R) = 0x1234;
    put_word(locked);
    put_word(tr);
    put_word(dr);
    put_word(RTC(ISR) & 0x70);                /* INITS, RSF; INITF gone */
    put_word(RTC(BKP0R));
    put_word(rsf_cleared);
    console_puts("\n");
    for (;;) __asm__ volatile("wfi");
}
