/* tests/mcu: interrupts from TIM2, EXTI0 (leg switch 0 on PB0) and bxCAN1, counted for
   200 ms of virtual time and printed on the console (semihosting). */
#include "board.h"
#define TIM2(o) REG(0x40000000 + (o))
#define EXTI(o) REG(0x40013C00 + (o))
#define SYSCFG_EXTICR1 REG(0x40013808)
#define CAN(o) REG(0x40006400 + (o))

static volatile uint32_t ticks, tim, falls, can_rx, last_id;
void SysTick_Handler(void) { ticks++; }
void TIM2_IRQHandler(void) { TIM2(0x10) = 0; tim++; }
void EXTI0_IRQHandler(void) { EXTI(0x14) = 1; falls++; }
void CAN1_RX0_IRQHandler(void) {
    last_id = CAN(0x1B0) >> 21;
    uint32_t data = CAN(0x1B8);
    CAN(0x0C) = 1 << 5;                       /* release the FIFO mailbox */
    can_rx++;
    CAN(0x184) = 4;                           /* echo: id + 1, same 4 bytes */
    CAN(0x188) = data;
    CAN(0x180) = ((last_id + 1) << 21) | 1;
}

static void say(const char *s) {
    register int r0 __asm("r0") = 4;
    register const char *r1 __asm("r1") = s;
    __asm volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
}
static char *num(char *p, uint32_t v) {
    char t[12]; int n = 0;
    do { t[n++] = '0' + v % 10; v /= 10; } while (v);
    while (n) *p++ = t[--n];
    *p++ = ' ';
    return p;
}

int main(void) {
    clock_100mhz();
    SYST_RVR = 100000 - 1; SYST_CVR = 0; SYST_CSR = 7;
    RCC_APB1ENR |= 1 | (1 << 25);             /* TIM2, CAN1 */
    RCC_AHB1ENR |= 2;                         /* GPIOB */
    RCC_APB2ENR |= 1 << 14;                   /* SYSCFG */
    TIM2(0x28) = 100 - 1;                     /* 100 MHz timer clock (APB1 /2, x2) / 100 */
    TIM2(0x2C) = 1000 - 1;                    /* -> 1 kHz updates */
    TIM2(0x0C) = 1;
    TIM2(0x00) = 1;
    NVIC_ISER(0) = (1u << 28) | (1u << 6) | (1u << 20);
    GPIOB(0x0C) = 1;                          /* PB0 pull-up */
    SYSCFG_EXTICR1 = 1;                       /* EXTI0 <- port B */
    EXTI(0x0C) = 1;                           /* falling edge: pressed */
    EXTI(0x00) = 1;
    CAN(0x00) = 1;                            /* init mode, out of sleep */
    while (!(CAN(0x04) & 1)) {}
    CAN(0x14) = 2;                            /* FMPIE0 */
    CAN(0x00) = 0;                            /* normal mode */
    while (CAN(0x04) & 1) {}
    CAN(0x184) = 2; CAN(0x188) = 0xBEEF; CAN(0x180) = (0x321 << 21) | 1;
    while (ticks < 200) __asm volatile("wfi");
    char line[96], *p = line;
    p = num(p, tim); p = num(p, falls); p = num(p, can_rx); p = num(p, last_id);
    p = num(p, (GPIOB(0x10) & 1));
    *p++ = '\n'; *p = 0;
    say(line);
    for (;;) __asm volatile("wfi");
}
