/* tests/mcu: waits on RAM that only an interrupt changes, as ST's HAL_Delay waits on uwTick
 * and a user's `while (!flag) {}` on a flag. SysTick at 1 kHz counts `ticks`; the firmware
 * waits 200 ticks in a loop that reads only RAM (WAIT=1), or in one that also counts its
 * passes in RAM (WAIT=2: never a fixed point, so it must run pass by pass), then waits for a
 * flag TIM-less: SysTick's handler sets `flag` at tick 300. Prints the ticks, the DWT cycles
 * the first wait took, and the passes counted. WAIT=3: the WAIT=1 loop with SysTick at
 * 100 Hz (20 ticks, the flag at 30) and EXTI0's interrupt mask set (the board then sleeps to now each
 * millisecond: events between the ticks that change nothing the loop reads). */
#include "board.h"

#if WAIT == 3
#define WAIT_TICKS 20
#define FLAG_TICK 30
#else
#define WAIT_TICKS 200
#define FLAG_TICK 300
#endif

volatile uint32_t ticks, flag, passes;

void SysTick_Handler(void) {
    ticks++;
    if (ticks == FLAG_TICK) flag = 1;
}

static uint32_t get_tick(void) { return ticks; }

int main(void) {
    clock_100mhz();
    console_init();
    DEMCR |= 1u << 24;
    DWT_CTRL |= 1;
#if WAIT == 3
    *(volatile uint32_t *)0x40013C00 = 1;     /* EXTI_IMR: line 0 */
    SYST_RVR = 1000000 - 1;
#else
    SYST_RVR = 100000 - 1;
#endif
    SYST_CVR = 0;
    SYST_CSR = 7;
    uint32_t start = get_tick(), c0 = DWT_CYCCNT;
    while (get_tick() - start < WAIT_TICKS) {
#if WAIT == 2
        passes++;
#endif
    }
    uint32_t cycles = DWT_CYCCNT - c0;
    while (!flag) {}
    put_dec(ticks);
    console_puts(" ");
    put_dec(cycles);
    console_puts(" ");
    put_dec(passes);
    console_puts(" ");
    console_puts("\n");
    for (;;) __asm__ volatile("wfi");
}
