/* HAL_UART_* and HAL_HalfDuplex_* on the F411's USART1, USART2 and USART6 (RM0383 section
 * 19): blocking transfers that poll SR, interrupt-driven ones (RXNE, TXE, TC) and DMA ones
 * on the streams of RM0383's request mapping. The default HAL_UART_MspInit wires the robot's
 * board (USART2 on PA2/PA3, USART1 on PA9/PA10, USART6 on PA11/PA12) and enables the IRQs;
 * the SDK's USARTx and DMA stream handlers find the handle HAL_UART_Init was given. The
 * half-duplex turn is Cube's: TE or RE alone in CR1, with HDSEL in CR3. */
#include "stm32f4xx_hal.h"

struct port {
    USART_TypeDef *usart;
    DMA_TypeDef *dma;
    uint8_t tx_stream, rx_stream, channel;
    IRQn_Type irq, tx_irq, rx_irq;
    GPIO_TypeDef *gpio;
    uint16_t pins;
    uint8_t af;
};

static const struct port PORTS[3] = {
    {USART1, DMA2, 7, 2, 4, USART1_IRQn, DMA2_Stream7_IRQn, DMA2_Stream2_IRQn, GPIOA,
     GPIO_PIN_9 | GPIO_PIN_10, GPIO_AF7_USART1},
    {USART2, DMA1, 6, 5, 4, USART2_IRQn, DMA1_Stream6_IRQn, DMA1_Stream5_IRQn, GPIOA,
     GPIO_PIN_2 | GPIO_PIN_3, GPIO_AF7_USART2},
    {USART6, DMA2, 6, 1, 5, USART6_IRQn, DMA2_Stream6_IRQn, DMA2_Stream1_IRQn, GPIOA,
     GPIO_PIN_11 | GPIO_PIN_12, GPIO_AF8_USART6},
};
static UART_HandleTypeDef *handles[3];

static int index_of(const USART_TypeDef *u)
{
    for (int i = 0; i < 3; i++)
        if (PORTS[i].usart == u)
            return i;
    return -1;
}

static const struct port *port_of(const UART_HandleTypeDef *h)
{
    int i = index_of(h->Instance);
    return i < 0 ? NULL : &PORTS[i];
}

void __weak HAL_UART_MspInit(UART_HandleTypeDef *huart)
{
    const struct port *p = port_of(huart);
    GPIO_InitTypeDef io = {0};
    if (huart->Instance == USART2)
        __HAL_RCC_USART2_CLK_ENABLE();
    else if (huart->Instance == USART1)
        __HAL_RCC_USART1_CLK_ENABLE();
    else
        __HAL_RCC_USART6_CLK_ENABLE();
    __HAL_RCC_GPIOA_CLK_ENABLE();
    hx_rcc_enable(&RCC->AHB1ENR, p->dma == DMA1 ? RCC_AHB1ENR_DMA1EN : RCC_AHB1ENR_DMA2EN);
    io.Pin = p->pins;
    io.Mode = GPIO_MODE_AF_PP;
    io.Pull = GPIO_PULLUP;
    io.Speed = GPIO_SPEED_FREQ_VERY_HIGH;
    io.Alternate = p->af;
    HAL_GPIO_Init(p->gpio, &io);
    HAL_NVIC_SetPriority(p->irq, 5, 0);
    HAL_NVIC_EnableIRQ(p->irq);
    HAL_NVIC_SetPriority(p->tx_irq, 5, 0);
    HAL_NVIC_EnableIRQ(p->tx_irq);
    HAL_NVIC_SetPriority(p->rx_irq, 5, 0);
    HAL_NVIC_EnableIRQ(p->rx_irq);
}

void __weak HAL_UART_TxCpltCallback(UART_HandleTypeDef *huart) { (void)huart; }
void __weak HAL_UART_RxCpltCallback(UART_HandleTypeDef *huart) { (void)huart; }
void __weak HAL_UART_ErrorCallback(UART_HandleTypeDef *huart) { (void)huart; }

/* BRR for the baud at the USART's bus clock: f_PCLK / baud in sixteenths at 16x
 * oversampling; at 8x the fraction has three bits. */
static uint32_t brr(const UART_HandleTypeDef *h)
{
    uint32_t pclk = h->Instance == USART2 ? HAL_RCC_GetPCLK1Freq() : HAL_RCC_GetPCLK2Freq();
    uint32_t div = (pclk + h->Init.BaudRate / 2u) / h->Init.BaudRate;
    if (h->Init.OverSampling == UART_OVERSAMPLING_8)
        return ((div & ~7u) << 1) | (div & 7u);
    return div;
}

static HAL_StatusTypeDef init(UART_HandleTypeDef *h, int halfduplex)
{
    if (h == NULL || port_of(h) == NULL || h->Init.BaudRate == 0)
        return HAL_ERROR;
    if (h->gState == HAL_UART_STATE_RESET)
        HAL_UART_MspInit(h);
    USART_TypeDef *u = h->Instance;
    u->CR1 = 0;
    u->CR2 = h->Init.StopBits;
    u->CR3 = halfduplex ? USART_CR3_HDSEL : 0u;
    u->BRR = brr(h);
    u->CR1 = h->Init.WordLength | h->Init.Parity | h->Init.Mode | h->Init.OverSampling |
             USART_CR1_UE;
    handles[index_of(u)] = h;
    h->ErrorCode = HAL_UART_ERROR_NONE;
    h->gState = HAL_UART_STATE_READY;
    h->RxState = HAL_UART_STATE_READY;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Init(UART_HandleTypeDef *huart) { return init(huart, 0); }
HAL_StatusTypeDef HAL_HalfDuplex_Init(UART_HandleTypeDef *huart) { return init(huart, 1); }

static HAL_StatusTypeDef turn(UART_HandleTypeDef *h, uint32_t enable)
{
    if (h == NULL || h->gState != HAL_UART_STATE_READY)
        return HAL_BUSY;
    h->Instance->CR1 = (h->Instance->CR1 & ~(USART_CR1_TE | USART_CR1_RE)) | enable;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_HalfDuplex_EnableTransmitter(UART_HandleTypeDef *huart)
{
    return turn(huart, USART_CR1_TE);
}

HAL_StatusTypeDef HAL_HalfDuplex_EnableReceiver(UART_HandleTypeDef *huart)
{
    return turn(huart, USART_CR1_RE);
}

/* Cube's checks before a transfer: HAL_BUSY while that direction is busy (or before
 * init), HAL_ERROR without data. */
static HAL_StatusTypeDef can_start(const UART_HandleTypeDef *h, int rx, const void *data,
                                   uint16_t size)
{
    if (h == NULL || (rx ? h->RxState : h->gState) != HAL_UART_STATE_READY)
        return HAL_BUSY;
    return data == NULL || size == 0 ? HAL_ERROR : HAL_OK;
}

/* Polls SR for `flag` until the tick says `timeout_ms` passed since `start`. */
static HAL_StatusTypeDef wait_flag(USART_TypeDef *u, uint32_t flag, uint32_t start,
                                   uint32_t timeout_ms)
{
    while (!(u->SR & flag)) {
        if (timeout_ms != HAL_MAX_DELAY &&
            (timeout_ms == 0u || HAL_GetTick() - start > timeout_ms))
            return HAL_TIMEOUT;
    }
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Transmit(UART_HandleTypeDef *huart, const uint8_t *pData,
                                    uint16_t Size, uint32_t Timeout)
{
    HAL_StatusTypeDef st = can_start(huart, 0, pData, Size);
    if (st != HAL_OK)
        return st;
    USART_TypeDef *u = huart->Instance;
    uint32_t start = HAL_GetTick();
    huart->gState = HAL_UART_STATE_BUSY_TX;
    for (uint16_t i = 0; i < Size && st == HAL_OK; i++) {
        st = wait_flag(u, USART_SR_TXE, start, Timeout);
        if (st == HAL_OK)
            u->DR = pData[i];
    }
    if (st == HAL_OK)
        st = wait_flag(u, USART_SR_TC, start, Timeout);   /* the last stop bit is out */
    huart->gState = HAL_UART_STATE_READY;
    return st;
}

HAL_StatusTypeDef HAL_UART_Receive(UART_HandleTypeDef *huart, uint8_t *pData,
                                   uint16_t Size, uint32_t Timeout)
{
    HAL_StatusTypeDef st = can_start(huart, 1, pData, Size);
    if (st != HAL_OK)
        return st;
    USART_TypeDef *u = huart->Instance;
    uint32_t start = HAL_GetTick();
    huart->RxState = HAL_UART_STATE_BUSY_RX;
    for (uint16_t i = 0; i < Size && st == HAL_OK; i++) {
        st = wait_flag(u, USART_SR_RXNE, start, Timeout);
        if (st == HAL_OK)
            pData[i] = (uint8_t)u->DR;
    }
    huart->RxState = HAL_UART_STATE_READY;
    return st;
}

/* ---- interrupt-driven -------------------------------------------------------------------- */
HAL_StatusTypeDef HAL_UART_Transmit_IT(UART_HandleTypeDef *huart, const uint8_t *pData,
                                       uint16_t Size)
{
    HAL_StatusTypeDef ok = can_start(huart, 0, pData, Size);
    if (ok != HAL_OK)
        return ok;
    huart->pTxBuffPtr = pData;
    huart->TxXferSize = huart->TxXferCount = Size;
    huart->gState = HAL_UART_STATE_BUSY_TX;
    huart->Instance->CR1 |= USART_CR1_TXEIE;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Receive_IT(UART_HandleTypeDef *huart, uint8_t *pData,
                                      uint16_t Size)
{
    HAL_StatusTypeDef ok = can_start(huart, 1, pData, Size);
    if (ok != HAL_OK)
        return ok;
    huart->pRxBuffPtr = pData;
    huart->RxXferSize = huart->RxXferCount = Size;
    huart->ErrorCode = HAL_UART_ERROR_NONE;
    huart->RxState = HAL_UART_STATE_BUSY_RX;
    huart->Instance->CR3 |= USART_CR3_EIE;
    huart->Instance->CR1 |= USART_CR1_RXNEIE;
    return HAL_OK;
}

void HAL_UART_IRQHandler(UART_HandleTypeDef *huart)
{
    USART_TypeDef *u = huart->Instance;
    uint32_t sr = u->SR, cr1 = u->CR1;
    uint32_t errors = sr & (USART_SR_PE | USART_SR_FE | USART_SR_NE | USART_SR_ORE);
    if (errors && (cr1 & USART_CR1_RXNEIE)) {
        huart->ErrorCode |= errors;   /* PE, FE, NE, ORE: Cube's error codes' bits */
        if (!(sr & USART_SR_RXNE))
            (void)u->DR;              /* SR then DR clears them */
        HAL_UART_ErrorCallback(huart);
    }
    if ((sr & USART_SR_RXNE) && (cr1 & USART_CR1_RXNEIE)) {
        *huart->pRxBuffPtr++ = (uint8_t)u->DR;
        if (--huart->RxXferCount == 0u) {
            u->CR1 &= ~USART_CR1_RXNEIE;
            u->CR3 &= ~USART_CR3_EIE;
            huart->RxState = HAL_UART_STATE_READY;
            HAL_UART_RxCpltCallback(huart);
        }
    }
    if ((sr & USART_SR_TXE) && (cr1 & USART_CR1_TXEIE)) {
        u->DR = *huart->pTxBuffPtr++;
        if (--huart->TxXferCount == 0u)
            u->CR1 = (u->CR1 & ~USART_CR1_TXEIE) | USART_CR1_TCIE;
    }
    if ((sr & USART_SR_TC) && (cr1 & USART_CR1_TCIE)) {
        u->CR1 &= ~USART_CR1_TCIE;
        huart->gState = HAL_UART_STATE_READY;
        HAL_UART_TxCpltCallback(huart);
    }
}

/* ---- DMA --------------------------------------------------------------------------------- */
static void stream_flags_clear(DMA_TypeDef *dma, uint32_t s)
{
    volatile uint32_t *ifcr = s < 4u ? &dma->LIFCR : &dma->HIFCR;
    *ifcr = DMA_FLAG_ALL << DMA_FLAG_SHIFT(s);
}

static void stream_stop(DMA_TypeDef *dma, uint32_t s)
{
    dma->S[s].CR &= ~DMA_SxCR_EN;
    while (dma->S[s].CR & DMA_SxCR_EN) {
    }
    stream_flags_clear(dma, s);
}

static void stream_start(const struct port *p, uint32_t s, const void *mem, uint16_t n,
                         uint32_t dir)
{
    DMA_Stream_TypeDef *st = &p->dma->S[s];
    stream_stop(p->dma, s);
    st->PAR = (uint32_t)(uintptr_t)&p->usart->DR;
    st->M0AR = (uint32_t)(uintptr_t)mem;
    st->NDTR = n;
    st->FCR = 0;   /* direct mode */
    st->CR = ((uint32_t)p->channel << DMA_SxCR_CHSEL_Pos) | DMA_SxCR_MINC | dir |
             DMA_SxCR_TCIE | DMA_SxCR_TEIE;
    st->CR |= DMA_SxCR_EN;
}

HAL_StatusTypeDef HAL_UART_Transmit_DMA(UART_HandleTypeDef *huart, const uint8_t *pData,
                                        uint16_t Size)
{
    HAL_StatusTypeDef ok = can_start(huart, 0, pData, Size);
    if (ok != HAL_OK)
        return ok;
    const struct port *p = port_of(huart);
    huart->pTxBuffPtr = pData;
    huart->TxXferSize = huart->TxXferCount = Size;
    huart->gState = HAL_UART_STATE_BUSY_TX;
    stream_start(p, p->tx_stream, pData, Size, DMA_SxCR_DIR_M2P);
    huart->Instance->SR = ~USART_SR_TC;   /* TC is cleared by writing 0 */
    huart->Instance->CR3 |= USART_CR3_DMAT;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Receive_DMA(UART_HandleTypeDef *huart, uint8_t *pData,
                                       uint16_t Size)
{
    HAL_StatusTypeDef ok = can_start(huart, 1, pData, Size);
    if (ok != HAL_OK)
        return ok;
    const struct port *p = port_of(huart);
    huart->pRxBuffPtr = pData;
    huart->RxXferSize = huart->RxXferCount = Size;
    huart->ErrorCode = HAL_UART_ERROR_NONE;
    huart->RxState = HAL_UART_STATE_BUSY_RX;
    stream_start(p, p->rx_stream, pData, Size, 0u);
    (void)huart->Instance->SR;            /* a stale overrun: SR then DR clears it */
    (void)huart->Instance->DR;
    huart->Instance->CR3 |= USART_CR3_DMAR;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_AbortReceive(UART_HandleTypeDef *huart)
{
    const struct port *p = port_of(huart);
    huart->Instance->CR1 &= ~USART_CR1_RXNEIE;
    huart->Instance->CR3 &= ~(USART_CR3_EIE | USART_CR3_DMAR);
    if (p->dma->S[p->rx_stream].CR & DMA_SxCR_EN)
        stream_stop(p->dma, p->rx_stream);
    huart->RxXferCount = 0;
    huart->RxState = HAL_UART_STATE_READY;
    return HAL_OK;
}

/* A stream's interrupt: transfer complete or error of the TX or RX stream of port `i`. */
static void dma_irq(int i, int tx)
{
    const struct port *p = &PORTS[i];
    UART_HandleTypeDef *h = handles[i];
    uint32_t s = tx ? p->tx_stream : p->rx_stream;
    uint32_t flags = (s < 4u ? p->dma->LISR : p->dma->HISR) >> DMA_FLAG_SHIFT(s);
    stream_flags_clear(p->dma, s);
    if (h == NULL)
        return;
    if (flags & DMA_FLAG_TEIF) {
        h->ErrorCode |= HAL_UART_ERROR_DMA;
        HAL_UART_ErrorCallback(h);
    }
    if (!(flags & DMA_FLAG_TCIF))
        return;
    if (tx) {   /* the last byte is in the shift register: TC ends the transfer */
        h->TxXferCount = 0;
        h->Instance->CR3 &= ~USART_CR3_DMAT;
        h->Instance->CR1 |= USART_CR1_TCIE;
    } else {
        h->RxXferCount = 0;
        h->Instance->CR3 &= ~(USART_CR3_DMAR | USART_CR3_EIE);
        h->RxState = HAL_UART_STATE_READY;
        HAL_UART_RxCpltCallback(h);
    }
}

static void usart_irq(int i)
{
    if (handles[i] != NULL)
        HAL_UART_IRQHandler(handles[i]);
}

void __weak USART1_IRQHandler(void) { usart_irq(0); }
void __weak USART2_IRQHandler(void) { usart_irq(1); }
void __weak USART6_IRQHandler(void) { usart_irq(2); }
void __weak DMA2_Stream7_IRQHandler(void) { dma_irq(0, 1); }
void __weak DMA2_Stream2_IRQHandler(void) { dma_irq(0, 0); }
void __weak DMA1_Stream6_IRQHandler(void) { dma_irq(1, 1); }
void __weak DMA1_Stream5_IRQHandler(void) { dma_irq(1, 0); }
void __weak DMA2_Stream6_IRQHandler(void) { dma_irq(2, 1); }
void __weak DMA2_Stream1_IRQHandler(void) { dma_irq(2, 0); }
