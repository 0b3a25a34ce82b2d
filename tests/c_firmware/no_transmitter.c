/* A firmware with the classic half-duplex mistake: it never drives the direction line
 * (PA1) high, so its packets never reach the servos. Every receive must time out; one
 * that does not exits 3 (tests/test_c_sdk.py). */
#include "stm32f4xx_hal.h"

#include <stdlib.h>

UART_HandleTypeDef huart2;

int main(void)
{
    uint8_t ping[6] = {0xFF, 0xFF, 1, 2, 0x01, 0xFB}, status[6];
    HAL_Init();
    huart2.Instance = USART2;
    huart2.Init.BaudRate = 1000000;
    huart2.Init.Mode = UART_MODE_TX_RX;
    HAL_HalfDuplex_Init(&huart2);
    for (;;) {
        HAL_UART_Transmit(&huart2, ping, sizeof ping, 10);
        if (HAL_UART_Receive(&huart2, status, sizeof status, 10) != HAL_TIMEOUT)
            exit(3);
        HAL_Delay(19);
    }
}
