/* tests/mcu: bare metal from RM0383: PLL 100 MHz, SysTick 1 ms, DWT, USART2 at 1 Mbps
   through the PA1 buffer pinging 18 servos, a console line on USART1, then WFI.
   TURN_AT_TXE=1 turns PA1 low at the last byte's TXE instead of TC: the byte is cut. */
#include "board.h"
#ifndef TURN_AT_TXE
#define TURN_AT_TXE 0
#endif
static volatile uint32_t ticks;
void SysTick_Handler(void) { ticks++; }

static void line_init(void) {                  /* USART2 PA2/PA3 AF7, PA1 output */
    RCC_AHB1ENR |= 1;
    RCC_APB1ENR |= 1 << 17;
    GPIOA(0x00) = (GPIOA(0x00) & ~(0xFu << 2)) | (1 << 2) | (2 << 4) | (2 << 6);
    GPIOA(0x20) |= (7 << 8) | (7 << 12);
    USART2(BRR) = BAUD_BRR;                    /* 50 MHz / 1 Mbps */
    USART2(CR1) = (1 << 13) | (1 << 3) | (1 << 2);
}

static int ping(int id) {
    uint8_t pkt[6] = {0xFF, 0xFF, (uint8_t)id, 2, 1, 0};
    pkt[5] = (uint8_t)~(id + 2 + 1);
    if (RAISE_A1) GPIOA(0x18) = 1 << 1;
    for (int i = 0; i < 6; i++) {
        while (!(USART2(SR) & (1 << 7))) {}
        USART2(DR) = pkt[i];
    }
    while (!(USART2(SR) & (1 << (TURN_AT_TXE ? 7 : 6)))) {}
    GPIOA(0x18) = 1 << (1 + 16);
    (void)USART2(DR);
    uint32_t t0 = ticks;
    int got = 0;
    while (got < 6 && ticks - t0 < 3) {
        if (USART2(SR) & (1 << 5)) { (void)USART2(DR); got++; }
    }
    return got == 6;
}

static char *num(char *p, uint32_t v) {
    char tmp[12]; int n = 0;
    do { tmp[n++] = '0' + v % 10; v /= 10; } while (v);
    while (n) *p++ = tmp[--n];
    return p;
}

int main(void) {
    clock_100mhz();
    SYST_RVR = 100000 - 1;
    SYST_CVR = 0;
    SYST_CSR = 7;
    DEMCR |= 1u << 24;
    DWT_CYCCNT = 0;
    DWT_CTRL |= 1;
    console_init();
    line_init();
    int n = 0;
    for (int id = 1; id <= 18; id++) n += ping(id);
    uint32_t t0 = ticks, c0 = DWT_CYCCNT;
    while (ticks - t0 < 1000) __asm volatile("wfi");
    uint32_t cycles = DWT_CYCCNT - c0;
    char line[64], *p = line;
    const char *a = "ping ";
    while (*a) *p++ = *a++;
    p = num(p, (uint32_t)n);
    *p++ = ' ';
    p = num(p, cycles);
    *p++ = '\n'; *p = 0;
    console_puts(line);
    for (;;) __asm volatile("wfi");
}
