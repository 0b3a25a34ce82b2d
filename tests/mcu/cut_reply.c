/* tests/mcu: PA1 raised again while a servo's status packet is still arriving (after its
   first byte): the receiver is off for the rest, the run names rx_while_transmitting. */
#include "board.h"

int main(void) {
    clock_100mhz();
    RCC_AHB1ENR |= 1;
    RCC_APB1ENR |= 1 << 17;
    GPIOA(0x00) = (GPIOA(0x00) & ~(0xFu << 2)) | (1 << 2) | (2 << 4) | (2 << 6);
    GPIOA(0x20) |= (7 << 8) | (7 << 12);
    USART2(BRR) = 50;                          /* 50 MHz / 1 Mbps */
    USART2(CR1) = (1 << 13) | (1 << 3) | (1 << 2);
    static const uint8_t ping[6] = {0xFF, 0xFF, 1, 2, 1, 0xFB};
    GPIOA(0x18) = 1 << 1;
    for (int i = 0; i < 6; i++) {
        while (!(USART2(SR) & (1 << 7))) {}
        USART2(DR) = ping[i];
    }
    while (!(USART2(SR) & (1 << 6))) {}
    GPIOA(0x18) = 1 << (1 + 16);
    while (!(USART2(SR) & (1 << 5))) {}        /* the status packet's first byte */
    GPIOA(0x18) = 1 << 1;                      /* transmit again: the rest is lost */
    for (;;) __asm volatile("wfi");
}
