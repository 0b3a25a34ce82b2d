/* tests/mcu: TIM1 as a HAL timebase (as CubeMX sets it for FreeRTOS projects): 1 kHz
 * update interrupts on TIM1_UP_TIM10 from APB2's timer clock (100 MHz, PSC 99, ARR 999),
 * and channel 1's compare at CCR1 = 0 on TIM1_CC each period. After 100 ticks it prints
 * the ticks, the compares and the DWT cycles they took. */
#include "board.h"

#define TIM1(o) REG(0x40010000 + (o))
#define CR1_ 0x00
#define DIER 0x0C
#define TSR 0x10
#define EGR 0x14
#define PSC 0x28
#define ARR 0x2C
#define CCR1 0x34

volatile uint32_t ticks, compares;

void TIM1_UP_TIM10_IRQHandler(void) {
    if (TIM1(TSR) & 1) {
        TIM1(TSR) = ~1u;
        ticks++;
    }
}

void TIM1_CC_IRQHandler(void) {
    if (TIM1(TSR) & 2) {
        TIM1(TSR) = ~2u;
        compares++;
    }
}

int main(void) {
    clock_100mhz();
    console_init();
    RCC_APB2ENR |= 1;                          /* TIM1 */
    TIM1(PSC) = 99;
    TIM1(ARR) = 999;
    TIM1(CCR1) = 0;
    TIM1(EGR) = 1;                             /* UG: PSC loaded */
    TIM1(TSR) = 0;
    TIM1(DIER) = 1 | 2;                        /* UIE, CC1IE */
    NVIC_ISER(0) = (1u << 25) | (1u << 27);
    DEMCR |= 1u << 24;
    DWT_CYCCNT = 0;
    DWT_CTRL |= 1;
    TIM1(CR1_) = 1;
    while (ticks < 100) __asm volatile("wfi");
    uint32_t cycles = DWT_CYCCNT;
    console_puts("tim1 ");
    put_dec(ticks);
    console_puts(" cc ");
    put_dec(compares);
    console_puts(" cycles ");
    put_dec(cycles);
    console_puts("\n");
    for (;;) __asm volatile("wfi");
}
