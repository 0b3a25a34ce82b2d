/* tests/mcu: what ends a run, and what must not: FAULT selects one. */
#include "board.h"

static void semihost(int op, const void *arg) {
    register int r0 __asm("r0") = op;
    register const void *r1 __asm("r1") = arg;
    __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
}

__attribute__((noinline)) void explode(void) { __asm volatile("udf #7"); }
__attribute__((noinline)) int deep(int n) { volatile int pad[64]; pad[0] = n; return n ? deep(n - 1) + pad[0] : 0; }
volatile uint32_t spins;

int main(void) {
    semihost(0x04, "semihosting says hi\n");
#if FAULT == 1
    explode();
#elif FAULT == 2
    (void)REG(0x60000000);
#elif FAULT == 3
    deep(100000);
#elif FAULT == 4
    static const uint32_t block[2] = {0x20026, 3};
    semihost(0x20, block);
#elif FAULT == 7
    static const uint32_t done[2] = {0x20026, 0};    /* SYS_EXIT 0 long before the end */
    semihost(0x20, done);
#elif FAULT == 8
    void (*volatile nowhere)(void) = 0;              /* a null function pointer called */
    nowhere();
#elif FAULT == 5
    uint32_t v = REG(0x40015800) + REG(0x40015804);   /* reserved, past SPI5: reads 0 */
    semihost(0x04, v == 0 ? "unmodelled reads 0\n" : "unmodelled reads junk\n");
#elif FAULT == 6
    console_init();                                  /* a poll loop that counts in RAM */
    for (int i = 0; i < 3; i++) {
        USART1(DR) = 'x';
        while (!(USART1(SR) & (1 << 7))) spins++;
    }
    char msg[] = "spins 0000000\n";
    uint32_t s = spins;
    for (int i = 12; i >= 6; i--) { msg[i] = '0' + s % 10; s /= 10; }
    semihost(0x04, msg);
#endif
    for (;;) __asm volatile("wfi");
}
