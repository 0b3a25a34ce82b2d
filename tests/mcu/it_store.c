/* tests/mcu: conditional stores inside IT blocks while an interrupt handler's register read
 * is being watched by the poll skipper. SysTick's handler reads SysTick->CTRL, as
 * MicroPython's does (to clear COUNTFLAG): the same read with the same value a tick apart
 * and nothing between them is a poll candidate, so the next pass is watched. Meanwhile the
 * thread pushes onto a small stack the way MicroPython's gc_mark_subtree does (`cmp; itte
 * ls; strhls; addls; strhi`) and checks every entry. Prints the rounds and the bad entries. */
#include "board.h"

static volatile uint16_t stack[64];
static volatile uint32_t overflow;
volatile uint32_t ticks;

void SysTick_Handler(void) {
    ticks++;
    (void)SYST_CSR;                     /* clears COUNTFLAG */
}

int main(void) {
    clock_100mhz();
    console_init();
    SYST_RVR = 100000 - 1;
    SYST_CVR = 0;
    SYST_CSR = 7;
    uint32_t rounds = 0, bad = 0;
    while (ticks < 40) {
        uint32_t n = 0;
        for (uint32_t i = 0; i < 100; i++) {
            __asm__ volatile(
                "cmp %[n], #63\n\t"
                "itte ls\n\t"
                "strhls %[v], [%[base], %[n], lsl #1]\n\t"
                "addls %[n], %[n], #1\n\t"
                "strhi %[v], [%[flag]]\n\t"
                : [n] "+r"(n)
                : [v] "r"(i), [base] "r"(stack), [flag] "r"(&overflow)
                : "cc", "memory");
        }
        for (uint32_t k = 0; k < 64; k++) bad += stack[k] != k;
        bad += n != 64;
        for (uint32_t k = 0; k < 64; k++) stack[k] = 0xFFFF;
        rounds++;
    }
    put_dec(rounds);
    console_puts(" ");
    put_dec(bad);
    console_puts(" ");
    console_puts("\n");
    for (;;) __asm__ volatile("wfi");
}
