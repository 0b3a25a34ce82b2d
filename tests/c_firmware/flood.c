/* A firmware that transmits for ever with the direction pin high, never receiving or
 * delaying (tests/test_never_hang.py): its posted writes must end the run as a verdict,
 * not grow the host's memory. */
#include "stm32f4xx_hal.h"

static UART_HandleTypeDef huart2;

int main(void)
{
    static uint8_t frame[64];
    HAL_Init();
    huart2.Instance = USART2;
    huart2.Init.BaudRate = 1000000;
    huart2.Init.Mode = UART_MODE_TX_RX;
    HAL_HalfDuplex_Init(&huart2);
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_SET);
    HAL_HalfDuplex_EnableTransmitter(&huart2);
    for (;;)
        HAL_UART_Transmit(&huart2, frame, sizeof frame, 10);
}
