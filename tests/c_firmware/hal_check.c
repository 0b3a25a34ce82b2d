/* The SDK's HAL against Cube's contract, in lockstep (tests/test_c_sdk.py): return codes,
 * a PING answered, an absent servo timing out in virtual time, HAL_Delay's extra tick, a
 * busy-wait that ends, the switch pins' idle level. A broken promise exits 10 + its number,
 * which hexhil run reports as a crash. */
#include "stm32f4xx_hal.h"

#include <stdlib.h>

_Static_assert(HAL_OK == 0 && HAL_ERROR == 1 && HAL_BUSY == 2 && HAL_TIMEOUT == 3,
               "Cube's HAL_StatusTypeDef values");
_Static_assert(GPIO_PIN_RESET == 0 && GPIO_PIN_SET == 1, "Cube's GPIO_PinState values");

UART_HandleTypeDef huart2;

static void check(int ok, int n) { if (!ok) exit(10 + n); }

static HAL_StatusTypeDef ping(uint8_t id, uint8_t *status)
{
    uint8_t p[6] = {0xFF, 0xFF, id, 2, 0x01, (uint8_t)~(id + 3)};
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_SET);
    HAL_HalfDuplex_EnableTransmitter(&huart2);
    HAL_UART_Transmit(&huart2, p, 6, 10);
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_RESET);
    HAL_HalfDuplex_EnableReceiver(&huart2);
    return HAL_UART_Receive(&huart2, status, 6, 10);
}

int main(void)
{
    uint8_t status[6];
    check(HAL_Init() == HAL_OK, 0);
    check(HAL_UART_Transmit(&huart2, status, 1, 10) == HAL_BUSY, 1);   /* not initialised */
    huart2.Instance = USART2;
    huart2.Init.BaudRate = 1000000;
    huart2.Init.Mode = UART_MODE_TX_RX;
    check(HAL_HalfDuplex_Init(&huart2) == HAL_OK, 2);
    check(HAL_UART_Transmit(&huart2, NULL, 1, 10) == HAL_ERROR, 3);
    check(ping(1, status) == HAL_OK && status[2] == 1 && status[4] == 0, 4);
    uint32_t t0 = HAL_GetTick();
    check(ping(99, status) == HAL_TIMEOUT, 5);            /* no servo 99 */
    check(HAL_GetTick() - t0 >= 10, 6);                   /* the time-out took virtual time */
    t0 = HAL_GetTick();
    HAL_Delay(5);
    check(HAL_GetTick() - t0 == 6, 7);                    /* Cube: one tick more than asked */
    t0 = HAL_GetTick();
    while (HAL_GetTick() - t0 < 3) {                      /* a busy-wait ends */
    }
    for (int i = 0; i < 6; i++)                           /* flat ground: no switch pressed */
        check(HAL_GPIO_ReadPin(GPIOB, (uint16_t)(1u << i)) == GPIO_PIN_SET, 8);
    for (;;)
        HAL_Delay(10);
}
