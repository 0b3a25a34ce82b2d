/* tests/mcu: register addresses from RM0383 for the emulator's test firmwares. */
#include <stdint.h>
#define REG(a) (*(volatile uint32_t *)(a))
#define RCC_CR REG(0x40023800)
#define RCC_PLLCFGR REG(0x40023804)
#define RCC_CFGR REG(0x40023808)
#define RCC_AHB1ENR REG(0x40023830)
#define RCC_APB1ENR REG(0x40023840)
#define RCC_APB2ENR REG(0x40023844)
#define FLASH_ACR REG(0x40023C00)
#define GPIOA(o) REG(0x40020000 + (o))
#define GPIOB(o) REG(0x40020400 + (o))
#define USART1(o) REG(0x40011000 + (o))
#define USART2(o) REG(0x40004400 + (o))
#define SYST_CSR REG(0xE000E010)
#define SYST_RVR REG(0xE000E014)
#define SYST_CVR REG(0xE000E018)
#define DEMCR REG(0xE000EDFC)
#define DWT_CTRL REG(0xE0001000)
#define DWT_CYCCNT REG(0xE0001004)
#define NVIC_ISER(n) REG(0xE000E100 + 4 * (n))
#define SCB_ICSR REG(0xE000ED04)
#define SR 0x00
#define DR 0x04
#define BRR 0x08
#define CR1 0x0C
#define CR3 0x14

static inline void clock_100mhz(void) {        /* HSI 16 MHz / 8 * 100 / 2 = 100 MHz */
    FLASH_ACR = 3;
    RCC_PLLCFGR = 8 | (100 << 6) | (0 << 16) | (4 << 24);
    RCC_CR |= 1 << 24;
    while (!(RCC_CR & (1 << 25))) {}
    RCC_CFGR = (4 << 10) | 2;                  /* APB1 /2 = 50 MHz, SYSCLK = PLL */
    while (((RCC_CFGR >> 2) & 3) != 2) {}
}

static inline void console_init(void) {        /* USART1 on PA9, 115200 at PCLK2 100 MHz */
    RCC_AHB1ENR |= 1;
    RCC_APB2ENR |= 1 << 4;
    USART1(BRR) = 868;
    USART1(CR1) = (1 << 13) | (1 << 3);
}

static inline void console_puts(const char *s) {
    while (*s) {
        while (!(USART1(SR) & (1 << 7))) {}
        USART1(DR) = *s++;
    }
}

static inline void put_word(uint32_t v) {         /* a word in hex and a space */
    char buf[10];
    for (int i = 0; i < 8; i++)
        buf[i] = "0123456789abcdef"[(v >> (28 - 4 * i)) & 0xF];
    buf[8] = ' ';
    buf[9] = 0;
    console_puts(buf);
}

static inline void put_dec(uint32_t v) {          /* a number in decimal */
    char buf[12];
    int i = 11;
    buf[i] = 0;
    do {
        buf[--i] = '0' + v % 10;
        v /= 10;
    } while (v);
    console_puts(buf + i);
}
