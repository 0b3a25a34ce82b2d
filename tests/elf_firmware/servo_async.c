/* Interrupt-driven (HAL_UART_Transmit_IT, HAL_UART_Receive_IT) or, built with -DUSE_DMA, DMA
 * (HAL_UART_Transmit_DMA, HAL_UART_Receive_DMA) exchanges with the 18 AX-12 servos: each
 * ping goes out while the core sleeps in WFI, the completion callbacks wake it, a status not
 * complete within 5 ms is aborted. Then servo 1's present position is read the same way.
 * The console says how many answered. */
#include "stm32f4xx_hal.h"

#include <stdio.h>

#ifdef USE_DMA
#define MODE "dma"
#define SEND HAL_UART_Transmit_DMA
#define RECEIVE HAL_UART_Receive_DMA
#else
#define MODE "it"
#define SEND HAL_UART_Transmit_IT
#define RECEIVE HAL_UART_Receive_IT
#endif

UART_HandleTypeDef huart2;
static volatile int tx_done, rx_done;

void HAL_UART_TxCpltCallback(UART_HandleTypeDef *huart)
{
    if (huart == &huart2)
        tx_done = 1;
}

void HAL_UART_RxCpltCallback(UART_HandleTypeDef *huart)
{
    if (huart == &huart2)
        rx_done = 1;
}

static uint16_t packet(uint8_t *p, uint8_t id, uint8_t inst, const uint8_t *params, uint8_t n)
{
    uint8_t sum = (uint8_t)(id + n + 2 + inst);
    p[0] = p[1] = 0xFF;
    p[2] = id;
    p[3] = (uint8_t)(n + 2);
    p[4] = inst;
    for (uint8_t i = 0; i < n; i++) {
        p[5 + i] = params[i];
        sum = (uint8_t)(sum + params[i]);
    }
    p[5 + n] = (uint8_t)~sum;
    return (uint16_t)(n + 6);
}

/* One instruction out and `want` status bytes back, sleeping in between; 1 if they came. */
static int exchange(const uint8_t *pkt, uint16_t n, uint8_t *reply, uint16_t want)
{
    tx_done = rx_done = 0;
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_SET);
    HAL_HalfDuplex_EnableTransmitter(&huart2);
    if (SEND(&huart2, pkt, n) != HAL_OK)
        return 0;
    while (!tx_done)
        __WFI();
    HAL_GPIO_WritePin(GPIOA, GPIO_PIN_1, GPIO_PIN_RESET);
    HAL_HalfDuplex_EnableReceiver(&huart2);
    if (RECEIVE(&huart2, reply, want) != HAL_OK)
        return 0;
    uint32_t start = HAL_GetTick();
    while (!rx_done && HAL_GetTick() - start < 5u)
        __WFI();
    if (!rx_done)
        HAL_UART_AbortReceive(&huart2);
    return rx_done;
}

int main(void)
{
    GPIO_InitTypeDef io = {0};
    uint8_t pkt[16], reply[8];
    HAL_Init();
    __HAL_RCC_GPIOA_CLK_ENABLE();
    io.Pin = GPIO_PIN_1;
    io.Mode = GPIO_MODE_OUTPUT_PP;
    HAL_GPIO_Init(GPIOA, &io);
    huart2.Instance = USART2;
    huart2.Init.BaudRate = 1000000;
    huart2.Init.Mode = UART_MODE_TX_RX;
    HAL_HalfDuplex_Init(&huart2);
    int answered = 0;
    for (uint8_t id = 1; id <= 18; id++)
        answered += exchange(pkt, packet(pkt, id, 0x01, NULL, 0), reply, 6) && reply[2] == id;
    static const uint8_t read_position[] = {36, 2};
    int pos = -1;
    if (exchange(pkt, packet(pkt, 1, 0x02, read_position, 2), reply, 8))
        pos = reply[5] | reply[6] << 8;
    printf("%s: %d of 18 servos answered, servo 1 at %d\n", MODE, answered, pos);
    for (;;)
        __WFI();
}
