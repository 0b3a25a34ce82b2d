/* HAL_UART_* and HAL_HalfDuplex_* for USART2, the servo line, over the link. Bytes go on
 * the line when the direction pin (GPIOA pin 1) is high and the transmitter is enabled;
 * the board core (hal_board.c) holds them and sends them with the next receive (one
 * transact) or the next sleep (a posted write). A status reaches the firmware when the pin is low and the receiver is enabled.
 * Bytes written with the pin low, or a status awaited with it high, are lost as on the
 * board: HAL_UART_Receive times out, and the mistake goes to the host as a fault event
 * (tx_while_receiving, rx_while_transmitting) that the run's summary counts. USART2's
 * Init.BaudRate goes to the host (a posted baud message): the servos hear the line at
 * their own rate, so at another rate none of them answers, as on the robot. */
#include "stm32f4xx_hal.h"
#include "hal_board.h"
#include "hexhil_link.h"

#include <stdio.h>
#include <string.h>

USART_TypeDef hexhil_usart1 = {1}, hexhil_usart2 = {2}, hexhil_usart6 = {6};

static int on_line(const UART_HandleTypeDef *h) { return h->Instance == USART2; }

static HAL_StatusTypeDef init(UART_HandleTypeDef *h, uint32_t halfduplex)
{
    if (h == NULL || h->Instance == NULL || h->Init.BaudRate == 0)
        return HAL_ERROR;
    hx_board_start();
    if (on_line(h))
        hx_board_baud(h->Init.BaudRate);   /* the line runs at it; the servos judge it */
    h->halfduplex = halfduplex;
    h->te = (h->Init.Mode & UART_MODE_TX) != 0;
    h->re = (h->Init.Mode & UART_MODE_RX) != 0;
    h->ErrorCode = HAL_UART_ERROR_NONE;
    h->gState = HAL_UART_STATE_READY;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Init(UART_HandleTypeDef *huart) { return init(huart, 0); }
HAL_StatusTypeDef HAL_HalfDuplex_Init(UART_HandleTypeDef *huart) { return init(huart, 1); }

/* CR1's TE and RE as the half-duplex turn leaves them. */
static HAL_StatusTypeDef turn(UART_HandleTypeDef *h, uint32_t te)
{
    if (h == NULL || h->gState != HAL_UART_STATE_READY)
        return HAL_BUSY;
    h->te = te;
    h->re = !te;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_HalfDuplex_EnableTransmitter(UART_HandleTypeDef *huart)
{
    return turn(huart, 1);
}

HAL_StatusTypeDef HAL_HalfDuplex_EnableReceiver(UART_HandleTypeDef *huart)
{
    return turn(huart, 0);
}

HAL_StatusTypeDef HAL_UART_Transmit(UART_HandleTypeDef *huart, const uint8_t *pData,
                                    uint16_t Size, uint32_t Timeout)
{
    (void)Timeout;
    if (huart == NULL || huart->gState != HAL_UART_STATE_READY)
        return HAL_BUSY;
    if (pData == NULL || Size == 0)
        return HAL_ERROR;
    hx_board_active();
    if (!on_line(huart) || !huart->te)
        return HAL_OK;   /* nothing wired there, or TE off: the bytes go nowhere */
    if (!hx_direction_tx()) {
        char detail[96];
        hx_count.tx_while_receiving++;
        snprintf(detail, sizeof detail, "%u bytes written while the direction pin (A1) was "
                 "low: they did not reach the line", Size);
        hx_board_fault("tx_while_receiving", detail);
        return HAL_OK;
    }
    hx_line_hold(pData, Size);
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Receive(UART_HandleTypeDef *huart, uint8_t *pData,
                                   uint16_t Size, uint32_t Timeout)
{
    if (huart == NULL || huart->gState != HAL_UART_STATE_READY)
        return HAL_BUSY;
    if (pData == NULL || Size == 0)
        return HAL_ERROR;
    if (!on_line(huart)) {
        hx_board_sleep(hx_now_us + (uint64_t)Timeout * 1000u);
        hx_board_active();
        return HAL_TIMEOUT;
    }
    uint32_t timeout_us = Timeout >= 0xFFFFFFFFu / 1000u ? 0xFFFFFFFFu : Timeout * 1000u;
    static uint8_t rx[HX_MAX_RX_LEN];
    uint16_t want = Size > HX_MAX_RX_LEN ? HX_MAX_RX_LEN : Size;
    uint16_t got = hx_line_transact(rx, want, timeout_us);
    hx_board_active();
    hx_board_check_end();
    if (hx_direction_tx() || !huart->re) {
        if (got) {
            char detail[96];
            hx_count.rx_while_transmitting++;
            snprintf(detail, sizeof detail, "%u status bytes arrived while the direction "
                     "pin (A1) was high: the receiver was off", got);
            hx_board_fault("rx_while_transmitting", detail);
        }
        got = 0;
    }
    memcpy(pData, rx, got);
    if (got < Size) {
        hx_count.timeouts++;
        return HAL_TIMEOUT;
    }
    return HAL_OK;
}
