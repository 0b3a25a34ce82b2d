/* tests/mcu: a firmware's own fault handlers, as CubeMX users write them. HANDLER selects:
 * 1 HardFault_Handler prints the stacked PC, CFSR and HFSR of an undefined instruction,
 *   then `while (1) {}`; 2 UsageFault enabled in SHCSR, its handler counts in a loop that
 *   never ends; 3 BusFault enabled, a read of nothing, its handler prints BFAR and resets
 *   the MCU (NVIC_SystemReset), the second boot runs on; 4 a write to nothing (imprecise)
 *   with the fault's registers printed, then `while (1) {}`. */
#include "board.h"

#define SHCSR REG(0xE000ED24)
#define CFSR REG(0xE000ED28)
#define HFSR REG(0xE000ED2C)
#define BFAR REG(0xE000ED38)
#define AIRCR REG(0xE000ED0C)

static void semihost(int op, const void *arg) {
    register int r0 __asm("r0") = op;
    register const void *r1 __asm("r1") = arg;
    __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
}

static void say(const char *what, uint32_t v) {      /* "what 0x12345678\n" */
    char buf[40];
    int n = 0;
    while (*what) buf[n++] = *what++;
    buf[n++] = ' ';
    for (int i = 0; i < 8; i++) buf[n++] = "0123456789abcdef"[(v >> (28 - 4 * i)) & 0xF];
    buf[n++] = '\n';
    buf[n] = 0;
    semihost(0x04, buf);
}

__attribute__((noinline)) void explode(void) { __asm volatile("udf #7"); }
__attribute__((noinline)) void store_nowhere(void) { REG(0x60000000) = 1; __asm volatile("nop"); }
#define BOOTS REG(0x20010000)            /* beyond .data/.bss: a reset keeps it */
volatile uint32_t spins;

void hard_fault_report(const uint32_t *sp) {         /* the faulting code's stacked frame */
    say("pc", sp[6]);
    say("cfsr", CFSR);
    say("hfsr", HFSR);
    while (1) {}
}

__attribute__((naked)) void HardFault_Handler(void) {
    __asm volatile("tst lr, #4\n ite eq\n mrseq r0, msp\n mrsne r0, psp\n b hard_fault_report");
}

void UsageFault_Handler(void) {
    say("usage cfsr", CFSR);
    for (;;) spins++;
}

void BusFault_Handler(void) {
    say("bus cfsr", CFSR);
    say("bfar", BFAR);
    AIRCR = 0x05FA0004;                           /* NVIC_SystemReset */
    for (;;) {}
}

int main(void) {
    BOOTS = BOOTS == 0xB0075 ? BOOTS + 1 : 0xB0075;
    say("boot", BOOTS);
#if HANDLER == 1
    explode();
#elif HANDLER == 2
    SHCSR |= 1 << 18;
    explode();
#elif HANDLER == 3
    if (BOOTS == 0xB0075) {
        SHCSR |= 1 << 17;
        (void)REG(0x60000004);
    }
#elif HANDLER == 4
    store_nowhere();
#endif
    for (;;) __asm volatile("wfi");
}
