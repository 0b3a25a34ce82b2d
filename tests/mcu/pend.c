/* tests/mcu: an interrupt pended by a register write (NVIC ISPR) is taken right after the
 * store, as on the chip, not when the emulator's chunk of instructions ends. The handler
 * notes DWT's cycle counter; main prints how many cycles after the store it ran. */
#include "board.h"

#define NVIC_ISPR(n) REG(0xE000E200 + 4 * (n))
#define TIM2_IRQ 28

static volatile uint32_t taken_at;
void TIM2_IRQHandler(void) { taken_at = DWT_CYCCNT; }

int main(void) {
    console_init();
    DEMCR |= 1u << 24;
    DWT_CTRL |= 1;
    NVIC_ISER(0) = 1u << TIM2_IRQ;
    uint32_t before = DWT_CYCCNT;
    NVIC_ISPR(0) = 1u << TIM2_IRQ;
    for (volatile int i = 0; i < 5000; i++) {}
    uint32_t after = taken_at - before;
    char msg[] = "taken after 0000000 cycles\n";
    for (int i = 18; i >= 12; i--) { msg[i] = '0' + after % 10; after /= 10; }
    console_puts(msg);
    for (;;) __asm volatile("wfi");
}
