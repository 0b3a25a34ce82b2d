/* A bare-metal firmware for the hexapod's STM32F411, written from RM0383 facts and
 * docs/elf-firmware.md alone: no HAL, no C library, only its own vector table and the SDK's
 * linker script (`hexhil sdk build --target stm32f411 --bare`). It sets the PLL from HSI to
 * 100 MHz, SysTick at 1 ms, counts cycles with DWT, pings the 18 AX-12 servos (Protocol 1.0,
 * IDs 1-18) on USART2 at 1 Mbps through the PA1 direction buffer, moves servo 1, reports on
 * USART1 and sleeps in WFI until the run ends. Build flags: -DNO_DIRECTION never drives PA1
 * high (the servos never hear it); -DSERVO_BAUD=57600 talks at the wrong speed. */
#include <stdint.h>

#ifndef SERVO_BAUD
#define SERVO_BAUD 1000000u
#endif

#define REG(addr) (*(volatile uint32_t *)(addr))
#define RCC_CR       REG(0x40023800u)
#define RCC_PLLCFGR  REG(0x40023804u)
#define RCC_CFGR     REG(0x40023808u)
#define RCC_AHB1ENR  REG(0x40023830u)
#define RCC_APB1ENR  REG(0x40023840u)
#define RCC_APB2ENR  REG(0x40023844u)
#define FLASH_ACR    REG(0x40023C00u)
#define GPIOA_MODER  REG(0x40020000u)
#define GPIOA_BSRR   REG(0x40020018u)
#define GPIOA_AFRL   REG(0x40020020u)
#define GPIOA_AFRH   REG(0x40020024u)
#define USART1_BASE  0x40011000u
#define USART2_BASE  0x40004400u
#define USART_SR(u)  REG((u) + 0x00u)
#define USART_DR(u)  REG((u) + 0x04u)
#define USART_BRR(u) REG((u) + 0x08u)
#define USART_CR1(u) REG((u) + 0x0Cu)
#define USART_CR3(u) REG((u) + 0x14u)
#define SR_RXNE (1u << 5)
#define SR_TC   (1u << 6)
#define SR_TXE  (1u << 7)
#define CR1_RE  (1u << 2)
#define CR1_TE  (1u << 3)
#define CR1_UE  (1u << 13)
#define SYST_CSR     REG(0xE000E010u)
#define SYST_RVR     REG(0xE000E014u)
#define SYST_CVR     REG(0xE000E018u)
#define DEMCR        REG(0xE000EDFCu)
#define DWT_CTRL     REG(0xE0001000u)
#define DWT_CYCCNT   REG(0xE0001004u)

#define SYSCLK_HZ 100000000u
#define PCLK1_HZ   50000000u
#define PCLK2_HZ  100000000u

extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss;
void Reset_Handler(void);
static void SysTick_Handler(void);
static void Hang(void) { for (;;) { } }

__attribute__((section(".isr_vector"), used))
static void (*const vectors[16])(void) = {
    (void (*)(void))(uintptr_t)&_estack, Reset_Handler, Hang, Hang, Hang, Hang, Hang,
    0, 0, 0, 0, Hang, Hang, 0, Hang, SysTick_Handler,
};

static volatile uint32_t ticks_ms;

static void SysTick_Handler(void) { ticks_ms++; }

static void clock_100mhz(void)
{
    FLASH_ACR = 3u;                                       /* 3 wait states at 100 MHz */
    RCC_PLLCFGR = 16u | (200u << 6) | (0u << 16) | (4u << 24);   /* HSI/16*200/2 */
    RCC_CR |= 1u << 24;                                   /* PLLON */
    while (!(RCC_CR & (1u << 25))) {                      /* PLLRDY */
    }
    RCC_CFGR = (4u << 10) | 2u;                           /* APB1 /2, SW = PLL */
    while (((RCC_CFGR >> 2) & 3u) != 2u) {                /* SWS = PLL */
    }
}

static void console_put(const char *s)
{
    for (; *s; s++) {
        while (!(USART_SR(USART1_BASE) & SR_TXE)) {
        }
        USART_DR(USART1_BASE) = (uint8_t)*s;
    }
    while (!(USART_SR(USART1_BASE) & SR_TC)) {
    }
}

static void console_num(uint32_t n)
{
    char buf[11];
    int i = 10;
    buf[i] = 0;
    do {
        buf[--i] = (char)('0' + n % 10u);
        n /= 10u;
    } while (n);
    console_put(&buf[i]);
}

static void direction(int transmit)
{
#ifdef NO_DIRECTION
    (void)transmit;
    GPIOA_BSRR = 1u << 17;                                /* PA1 stays low */
#else
    GPIOA_BSRR = transmit ? 1u << 1 : 1u << 17;
#endif
}

/* Sends one instruction packet and waits up to 2 ms for a status packet of `want` bytes;
 * returns how many bytes came. */
static uint32_t transact(const uint8_t *pkt, uint32_t n, uint8_t *reply, uint32_t want)
{
    direction(1);
    USART_CR1(USART2_BASE) = CR1_UE | CR1_TE;
    for (uint32_t i = 0; i < n; i++) {
        while (!(USART_SR(USART2_BASE) & SR_TXE)) {
        }
        USART_DR(USART2_BASE) = pkt[i];
    }
    while (!(USART_SR(USART2_BASE) & SR_TC)) {
    }
    direction(0);
    USART_CR1(USART2_BASE) = CR1_UE | CR1_RE;
    uint32_t got = 0, start = DWT_CYCCNT;
    while (got < want && DWT_CYCCNT - start < 2u * (SYSCLK_HZ / 1000u)) {
        if (USART_SR(USART2_BASE) & SR_RXNE)
            reply[got++] = (uint8_t)USART_DR(USART2_BASE);
    }
    return got;
}

static uint32_t packet(uint8_t *p, uint8_t id, uint8_t inst, const uint8_t *params,
                       uint32_t n)
{
    uint8_t sum = (uint8_t)(id + n + 2u + inst);
    p[0] = p[1] = 0xFF;
    p[2] = id;
    p[3] = (uint8_t)(n + 2u);
    p[4] = inst;
    for (uint32_t i = 0; i < n; i++) {
        p[5 + i] = params[i];
        sum = (uint8_t)(sum + params[i]);
    }
    p[5 + n] = (uint8_t)~sum;
    return n + 6u;
}

int main(void)
{
    uint8_t pkt[16], reply[8];
    clock_100mhz();
    SYST_RVR = SYSCLK_HZ / 1000u - 1u;                    /* 1 ms */
    SYST_CVR = 0;
    SYST_CSR = 7u;                                        /* processor clock, TICKINT, ENABLE */
    DEMCR |= 1u << 24;                                    /* TRCENA */
    DWT_CYCCNT = 0;
    DWT_CTRL |= 1u;                                       /* CYCCNTENA */

    RCC_AHB1ENR |= 1u << 0;                               /* GPIOA */
    RCC_APB1ENR |= 1u << 17;                              /* USART2 */
    RCC_APB2ENR |= 1u << 4;                               /* USART1 */
    /* PA1 output (direction), PA2/PA3 AF7 (USART2), PA9/PA10 AF7 (USART1) */
    GPIOA_MODER = (GPIOA_MODER & ~(0x3FFu << 2 | 0xFu << 18)) |
                  (1u << 2) | (2u << 4) | (2u << 6) | (2u << 18) | (2u << 20);
    GPIOA_AFRL = (GPIOA_AFRL & ~(0xFFu << 8)) | (7u << 8) | (7u << 12);
    GPIOA_AFRH = (GPIOA_AFRH & ~(0xFFu << 4)) | (7u << 4) | (7u << 8);
    direction(0);
    USART_BRR(USART1_BASE) = (PCLK2_HZ + 57600u) / 115200u;   /* 868: 115200 baud */
    USART_CR1(USART1_BASE) = CR1_UE | CR1_TE;
    USART_BRR(USART2_BASE) = (PCLK1_HZ + SERVO_BAUD / 2u) / SERVO_BAUD;
    USART_CR3(USART2_BASE) = 1u << 3;                     /* HDSEL: one wire */
    USART_CR1(USART2_BASE) = CR1_UE | CR1_RE;

    uint32_t answered = 0;
    for (uint8_t id = 1; id <= 18; id++) {
        if (transact(pkt, packet(pkt, id, 0x01, 0, 0), reply, 6) == 6 && reply[2] == id)
            answered++;
    }
    static const uint8_t torque_on[] = {24, 1};
    static const uint8_t goal_612[] = {30, 612 & 0xFF, 612 >> 8};
    transact(pkt, packet(pkt, 1, 0x03, torque_on, sizeof torque_on), reply, 6);
    uint32_t moved = transact(pkt, packet(pkt, 1, 0x03, goal_612, sizeof goal_612), reply, 6);

    console_put("bare-metal: ");
    console_num(answered);
    console_put(" of 18 servos answered, servo 1 ");
    console_put(moved == 6 ? "moved\n" : "did not answer\n");

    uint32_t t0 = ticks_ms;
    while (ticks_ms == t0) {
        __asm volatile ("wfi");
    }
    uint32_t c0 = DWT_CYCCNT, t1 = ticks_ms;
    while (ticks_ms - t1 < 1000u) {
        __asm volatile ("wfi");
    }
    uint32_t cycles = DWT_CYCCNT - c0;
    console_put("bare-metal: ");
    console_num(cycles);
    console_put(" cycles in 1000 SysTick ms\n");
    uint32_t ended = DWT_CYCCNT;                          /* the newline has left: TC */
    console_put("bare-metal: that line ended at cycle ");
    console_num(ended);
    console_put("\n");
    for (;;) {
        __asm volatile ("wfi");
    }
}

void Reset_Handler(void)
{
    uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;)
        *dst++ = *src++;
    for (uint32_t *dst = &_sbss; dst < &_ebss;)
        *dst++ = 0;
    main();
}
