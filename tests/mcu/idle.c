/* tests/mcu: the servo line read the way HAL_UARTEx_ReceiveToIdle_IT and _DMA read it, in
   registers: each ping's status is one burst ended by USART2's IDLE interrupt (IDLEIE),
   its length counted by the RXNE interrupt or, with USE_DMA=1, from DMA1 stream 5's NDTR;
   the flag cleared by a read of SR then DR. Then USART1 (its own line echoed with HDSEL)
   polls IDLE without IDLEIE. The console says how many pings came back whole, the bursts,
   the least and most DWT cycles from a burst's last RXNE to its IDLE (IT: one frame, 10 us
   at 1 Mbps, is 1000 cycles at 100 MHz), and whether USART1's IDLE came, cleared and
   stayed clear with no new byte. */
#include "board.h"
#ifndef USE_DMA
#define USE_DMA 0
#endif
#define CR3_HDSEL (1 << 3)
#define CR3_DMAR (1 << 6)
#define SR_IDLE (1 << 4)
#define SR_RXNE (1 << 5)
#define SR_TC (1 << 6)
#define SR_TXE (1 << 7)
#define CR1_UE (1 << 13)
#define CR1_TE (1 << 3)
#define CR1_RE (1 << 2)
#define CR1_IDLEIE (1 << 4)
#define CR1_RXNEIE (1 << 5)
#define DMA1_S5(o) REG(0x40026000 + 0x10 + 0x18 * 5 + (o))
#define DMA1_HIFCR REG(0x4002600C)
#define BUF 32

static volatile uint32_t ticks;
static uint8_t buf[BUF];
static volatile int got, bursts;
static volatile uint32_t last_rx, gap_min = 0xFFFFFFFF, gap_max;
void SysTick_Handler(void) { ticks++; }

void USART2_IRQHandler(void) {                 /* HAL_UART_IRQHandler's two branches */
    uint32_t sr = USART2(SR), cr1 = USART2(CR1);
    if ((sr & SR_RXNE) && (cr1 & CR1_RXNEIE)) {
        uint8_t b = (uint8_t)USART2(DR);
        if (got < BUF) buf[got++] = b;
        last_rx = DWT_CYCCNT;
    }
    if ((sr & SR_IDLE) && (cr1 & CR1_IDLEIE)) {
        (void)USART2(SR);                      /* __HAL_UART_CLEAR_IDLEFLAG */
        (void)USART2(DR);
        if (USE_DMA) {
            got = BUF - (int)DMA1_S5(0x04);    /* the bytes moved: BUF less NDTR */
            DMA1_S5(0x00) &= ~1u;
        }
        if (!USE_DMA) {
            uint32_t gap = DWT_CYCCNT - last_rx;
            gap_min = gap < gap_min ? gap : gap_min;
            gap_max = gap > gap_max ? gap : gap_max;
        }
        USART2(CR1) = CR1_UE;
        bursts++;
    }
}

static int ping(int id) {
    uint8_t pkt[6] = {0xFF, 0xFF, (uint8_t)id, 2, 1, 0};
    pkt[5] = (uint8_t)~(id + 2 + 1);
    GPIOA(0x18) = 1 << 1;                      /* PA1 high: the buffer transmits */
    USART2(CR1) = CR1_UE | CR1_TE;             /* HAL_HalfDuplex_EnableTransmitter */
    for (int i = 0; i < 6; i++) {
        while (!(USART2(SR) & SR_TXE)) {}
        USART2(DR) = pkt[i];
    }
    while (!(USART2(SR) & SR_TC)) {}
    GPIOA(0x18) = 1 << (1 + 16);
    got = 0;
    int before = bursts;
    if (USE_DMA) {
        DMA1_HIFCR = 0x3Fu << 6;               /* stream 5's flags */
        DMA1_S5(0x08) = 0x40004404;            /* PAR: USART2 DR */
        DMA1_S5(0x0C) = (uint32_t)buf;         /* M0AR */
        DMA1_S5(0x04) = BUF;                   /* NDTR */
        DMA1_S5(0x00) = (4u << 25) | (1u << 10) | 1u;   /* channel 4, MINC, to memory, EN */
        USART2(CR3) = CR3_HDSEL | CR3_DMAR;
    }
    (void)USART2(SR);                          /* the stale IDLE cleared, as the HAL does */
    (void)USART2(DR);
    USART2(CR1) = CR1_UE | CR1_RE | CR1_IDLEIE | (USE_DMA ? 0 : CR1_RXNEIE);
    uint32_t t0 = ticks;
    while (bursts == before && ticks - t0 < 3) __asm volatile("wfi");
    USART2(CR1) = CR1_UE;
    USART2(CR3) = CR3_HDSEL;
    return bursts == before + 1 && got == 6 && buf[2] == id;
}

static char *num(char *p, uint32_t v) {
    char tmp[12]; int n = 0;
    do { tmp[n++] = '0' + v % 10; v /= 10; } while (v);
    while (n) *p++ = tmp[--n];
    return p;
}

static char *text(char *p, const char *s) {
    while (*s) *p++ = *s++;
    return p;
}

int main(void) {
    clock_100mhz();
    SYST_RVR = 100000 - 1;
    SYST_CVR = 0;
    SYST_CSR = 7;
    DEMCR |= 1u << 24;
    DWT_CTRL |= 1;
    RCC_AHB1ENR |= 1 | (1u << 21);             /* GPIOA, DMA1 */
    RCC_APB1ENR |= 1 << 17;
    GPIOA(0x00) = (GPIOA(0x00) & ~(0xFu << 2)) | (1 << 2) | (2 << 4);   /* PA1 out, PA2 AF */
    GPIOA(0x20) |= 7 << 8;
    USART2(BRR) = 50;                          /* 50 MHz / 1 Mbps */
    USART2(CR3) = CR3_HDSEL;
    USART2(CR1) = CR1_UE;
    NVIC_ISER(1) = 1u << (38 - 32);            /* USART2 */
    int n = 0;
    for (int id = 1; id <= 18; id++) n += ping(id);
    console_init();
    USART1(CR3) = CR3_HDSEL;                   /* its own bytes come back */
    USART1(CR1) |= CR1_RE;
    char line[80], *p = line;
    p = text(p, USE_DMA ? "idle dma: " : "idle it: ");
    p = num(p, (uint32_t)n);
    p = text(p, " pings, ");
    p = num(p, (uint32_t)bursts);
    p = text(p, " bursts, gap ");
    p = num(p, USE_DMA ? 0 : gap_min);
    *p++ = ' ';
    p = num(p, gap_max);
    *p++ = '\n';
    *p = 0;
    console_puts(line);
    uint32_t t0 = ticks;
    while (!(USART1(SR) & SR_IDLE) && ticks - t0 < 5) {}
    int came = (USART1(SR) & SR_IDLE) != 0;
    (void)USART1(DR);                          /* SR then DR: cleared */
    int cleared = !(USART1(SR) & SR_IDLE);
    t0 = ticks;
    while (ticks - t0 < 2) {}
    int stayed = !(USART1(SR) & SR_IDLE);      /* no byte since: no new IDLE */
    console_puts(came && cleared && stayed ? "usart1 idle ok\n" : "usart1 idle wrong\n");
    for (;;) __asm volatile("wfi");
}
