/* tests/mcu: the exception model, rule by rule, as the ARMv7-M Architecture Reference Manual
 * (B1.5) gives it. Each check prints `name value` (hex) on its own line; the test knows what
 * the chip gives. Interrupts are pended by software (NVIC ISPR), so nothing depends on time:
 * TIM2 (IRQ 28), EXTI0 (IRQ 6) and CAN1_RX0 (IRQ 20) are plain handlers here. */
#include "board.h"

#define NVIC_ISPR(n) REG(0xE000E200 + 4 * (n))
#define NVIC_IPR8(n) (*(volatile uint8_t *)(0xE000E400 + (n)))
#define SCB_AIRCR REG(0xE000ED0C)
#define FPCCR REG(0xE000EF34)
#define TIM2_IRQ 28
#define EXTI0_IRQ 6
#define CAN_IRQ 20

static void put_hex(const char *name, uint32_t v) {
    char buf[10];
    console_puts(name);
    console_puts(" ");
    for (int i = 0; i < 8; i++)
        buf[i] = "0123456789abcdef"[(v >> (28 - 4 * i)) & 0xF];
    buf[8] = '\n';
    buf[9] = 0;
    console_puts(buf);
}

static void pend(int irq) { NVIC_ISPR(irq >> 5) = 1u << (irq & 31); }
static void enable(int irq, uint8_t prio) {
    NVIC_IPR8(irq) = prio;
    NVIC_ISER(irq >> 5) = 1u << (irq & 31);
}

static inline uint32_t lr_now(void) {
    uint32_t v;
    __asm__ volatile("mov %0, lr" : "=r"(v));
    return v;
}

/* what the handlers saw */
static volatile uint32_t tim2_lr, tim2_icsr, tim2_order, exti_lr, exti_icsr, can_lr, order;
static volatile uint32_t tim2_count, exti_count, can_count;
static volatile uint32_t nest;              /* TIM2 pends EXTI0 (higher) from inside */
static volatile uint32_t frame_xpsr, frame_sp;
static volatile float handler_float;

void __attribute__((noinline)) TIM2_IRQHandler(void) {
    tim2_lr = lr_now();
    tim2_icsr = SCB_ICSR;
    tim2_order = ++order;
    tim2_count++;
    if (nest) {
        nest = 0;
        pend(EXTI0_IRQ);                    /* preempts this handler at once */
        __asm__ volatile("dsb\n\tisb");
    }
    handler_float = handler_float * 3.0f + 1.0f;   /* clobbers S0-S15 */
}

void __attribute__((noinline)) EXTI0_IRQHandler(void) {
    exti_lr = lr_now();
    exti_icsr = SCB_ICSR;
    exti_count++;
    order++;
}

/* the frame's xPSR and where it was stacked: the handler's MSP at entry */
void __attribute__((naked)) CAN1_RX0_IRQHandler(void) {
    __asm__ volatile(
        "mrs r0, msp\n\t"
        "ldr r1, =frame_sp\n\t"
        "str r0, [r1]\n\t"
        "ldr r2, [r0, #28]\n\t"              /* the stacked xPSR */
        "ldr r1, =frame_xpsr\n\t"
        "str r2, [r1]\n\t"
        "ldr r1, =can_lr\n\t"
        "str lr, [r1]\n\t"
        "ldr r1, =can_count\n\t"
        "ldr r2, [r1]\n\t"
        "adds r2, #1\n\t"
        "str r2, [r1]\n\t"
        "bx lr\n\t"
        ".ltorg");
}

/* the CAN interrupt taken with SP at 8n + 4: returns SP before, SP after */
static uint32_t __attribute__((noinline)) misaligned_interrupt(uint32_t *after) {
    uint32_t before, back, saved;
    __asm__ volatile(
        "mov %2, sp\n\t"
        "bic %0, %2, #7\n\t"
        "sub %0, %0, #4\n\t"                 /* 8n + 4 */
        "mov sp, %0\n\t"
        "str %4, [%3]\n\t"                   /* NVIC ISPR: CAN1_RX0 */
        "dsb\n\tisb\n\t"
        "nop\n\tnop\n\t"
        "mov %1, sp\n\t"
        "mov sp, %2\n\t"
        : "=&r"(before), "=&r"(back), "=&r"(saved)
        : "r"(&NVIC_ISPR(0)), "r"(1u << CAN_IRQ)
        : "memory");
    *after = back;
    return before;
}

int main(void) {
    clock_100mhz();
    console_init();
    SCB_AIRCR = (0x05FAu << 16) | (3u << 8);   /* PRIGROUP 3: 4 bits of group priority */
    enable(TIM2_IRQ, 0x80);
    enable(EXTI0_IRQ, 0x40);
    enable(CAN_IRQ, 0x20);

    /* no FP instruction yet (CONTROL.FPCA 0): the basic frame, EXC_RETURN 0xFFFFFFF9 */
    uint32_t control;
    __asm__ volatile("mrs %0, control" : "=r"(control));
    put_hex("control_before_fp", control);
    pend(TIM2_IRQ);
    __asm__ volatile("dsb\n\tisb");
    put_hex("lr_thread_basic", tim2_lr);
    /* the handler's own float made its FP context active: back in thread mode, FPCA is
       what EXC_RETURN said (bit 4 set: none) */
    __asm__ volatile("mrs %0, control" : "=r"(control));
    put_hex("control_after_basic_return", control & 4);

    /* with S0-S15 live in the thread: the extended frame, 0xFFFFFFE9, S0-S15 and FPSCR
       back as they were though the handler computed in floats */
    float a = 1.5f, b;
    uint32_t fpscr_in = 0x00C00000u | 0x1, fpscr_out;   /* RMode round-to-zero, IOC set */
    __asm__ volatile(
        "vmsr fpscr, %[f]\n\t"
        "vmov s0, %[a]\n\t"
        "vmov s15, %[a]\n\t"
        "str %[bit], [%[ispr]]\n\t"
        "dsb\n\tisb\n\t"
        "vadd.f32 s1, s0, s15\n\t"
        "vmov %[b], s1\n\t"
        "vmrs %[o], fpscr\n\t"
        : [b] "=&r"(b), [o] "=&r"(fpscr_out)
        : [a] "r"(a), [f] "r"(fpscr_in), [ispr] "r"(&NVIC_ISPR(0)), [bit] "r"(1u << TIM2_IRQ)
        : "s0", "s1", "s15", "memory");
    put_hex("lr_thread_extended", tim2_lr);
    put_hex("float_kept", (uint32_t)(b * 1000.0f));
    put_hex("fpscr_kept", fpscr_out);
    put_hex("fpccr", FPCCR);

    /* preemption by a higher group priority from inside a handler: EXC_RETURN 0xFFFFFFE1
       (handler, extended frame), VECTACTIVE, RETTOBASE 0 there and 1 in the outer one */
    nest = 1;
    pend(TIM2_IRQ);
    __asm__ volatile("dsb\n\tisb");
    put_hex("lr_nested", exti_lr);
    put_hex("icsr_nested", exti_icsr & 0x1FF);
    put_hex("rettobase_nested", exti_icsr >> 11 & 1);
    put_hex("rettobase_outer", tim2_icsr >> 11 & 1);

    /* PRIMASK: nothing taken while set; both pending taken by priority, tail-chained, at
       CPSIE; the first one sees the second pending (VECTPENDING, ISRPENDING) */
    order = 0;
    uint32_t e0 = exti_count, t1 = tim2_count;
    __asm__ volatile("cpsid i" ::: "memory");
    pend(TIM2_IRQ);
    pend(EXTI0_IRQ);
    __asm__ volatile("dsb\n\tisb\n\tnop\n\tnop");
    uint32_t masked = (exti_count - e0) << 16 | (tim2_count - t1);
    __asm__ volatile("cpsie i\n\tisb" ::: "memory");
    uint32_t seen = order;
    put_hex("masked_counts", masked);
    put_hex("taken_at_cpsie", seen);
    put_hex("order_tim2", tim2_order);
    put_hex("vectpending_in_first", exti_icsr >> 12 & 0x1FF);

    /* BASEPRI 0x60: TIM2 (0x80) waits, CAN (0x20) does not; BASEPRI 0 lets TIM2 in */
    uint32_t t0 = tim2_count, c0 = can_count;
    __asm__ volatile("msr basepri, %0\n\tisb" :: "r"(0x60) : "memory");
    pend(TIM2_IRQ);
    pend(CAN_IRQ);
    __asm__ volatile("dsb\n\tisb\n\tnop\n\tnop");
    put_hex("basepri_counts", (tim2_count - t0) << 16 | (can_count - c0));
    __asm__ volatile("msr basepri, %0\n\tisb" :: "r"(0) : "memory");
    put_hex("basepri_released", tim2_count - t0);

    /* priority grouping: PRIGROUP 5 (2 bits of group): 0x40 and 0x60 are one group, so
       EXTI0 (0x40) pended inside TIM2 (0x60) waits for TIM2's return */
    SCB_AIRCR = (0x05FAu << 16) | (5u << 8);
    NVIC_IPR8(TIM2_IRQ) = 0x60;
    nest = 1;
    exti_lr = 0;
    pend(TIM2_IRQ);
    __asm__ volatile("dsb\n\tisb");
    put_hex("same_group_lr", exti_lr);     /* not nested: 0xFFFFFFE9 or F9 from thread */
    SCB_AIRCR = (0x05FAu << 16) | (3u << 8);

    /* the stack alignment bit: the CAN interrupt taken with SP = 8n + 4 stacks its frame at
       an 8-byte boundary, sets xPSR bit 9 in the frame, and the return gives SP back */
    uint32_t after;
    uint32_t before = misaligned_interrupt(&after);
    put_hex("sp_before_mod8", before & 7);
    put_hex("frame_mod8", frame_sp & 7);
    put_hex("frame_xpsr_bit9", frame_xpsr >> 9 & 1);
    put_hex("sp_back", after == before);
    put_hex("lr_naked", can_lr);
    console_puts("done\n");
    for (;;) __asm__ volatile("wfi");
}
