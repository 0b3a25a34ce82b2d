/* The C SDK's HAL subset (hexhil_hal_api.h) for the STM32F411 itself: ports and USARTs are
 * the registers of stm32f411xe.h, and the calls drive them as RM0383 describes (src/). Beyond
 * the host's subset the board has what only a real core can do: interrupt- and DMA-driven
 * UART transfers with Cube's completion callbacks, the NVIC, and the 100 MHz clock tree that
 * SystemInit sets up before main (docs/elf-firmware.md). */
#ifndef STM32F4XX_HAL_H
#define STM32F4XX_HAL_H

#include "hexhil_hal_api.h"
#include "stm32f411xe.h"

#ifdef __cplusplus
extern "C" {
#endif

struct __UART_HandleTypeDef {
    USART_TypeDef *Instance;
    UART_InitTypeDef Init;
    volatile HAL_UART_StateTypeDef gState;    /* the transmitter's */
    volatile HAL_UART_StateTypeDef RxState;   /* the receiver's */
    volatile uint32_t ErrorCode;
    const uint8_t *pTxBuffPtr;
    uint16_t TxXferSize;
    volatile uint16_t TxXferCount;
    uint8_t *pRxBuffPtr;
    uint16_t RxXferSize;
    volatile uint16_t RxXferCount;
};

#define HAL_UART_ERROR_PE  0x00000001U
#define HAL_UART_ERROR_NE  0x00000002U
#define HAL_UART_ERROR_FE  0x00000004U
#define HAL_UART_ERROR_ORE 0x00000008U
#define HAL_UART_ERROR_DMA 0x00000010U

/* Pins as interrupt sources (EXTI through SYSCFG's selection): Cube's mode codes. The
 * SDK's EXTIx_IRQHandler (weak) calls HAL_GPIO_EXTI_IRQHandler, which clears the pending
 * bit and calls HAL_GPIO_EXTI_Callback; the firmware enables the IRQ in the NVIC. */
#define GPIO_MODE_IT_RISING         0x10110000U
#define GPIO_MODE_IT_FALLING        0x10210000U
#define GPIO_MODE_IT_RISING_FALLING 0x10310000U
void HAL_GPIO_EXTI_IRQHandler(uint16_t GPIO_Pin);
void HAL_GPIO_EXTI_Callback(uint16_t GPIO_Pin);

/* The clock tree (system_stm32f411.c): SYSCLK 100 MHz from HSI through the PLL, APB1
 * 50 MHz, APB2 100 MHz; SystemInit sets it before main. */
extern uint32_t SystemCoreClock;
void SystemInit(void);
void SystemClock_Config100MHz(void);
void SystemCoreClockUpdate(void);
uint32_t HAL_RCC_GetSysClockFreq(void);
uint32_t HAL_RCC_GetHCLKFreq(void);
uint32_t HAL_RCC_GetPCLK1Freq(void);
uint32_t HAL_RCC_GetPCLK2Freq(void);

/* The tick: SysTick at 1 ms (HAL_InitTick, weak). A firmware with its own SysTick_Handler
 * calls HAL_IncTick. HAL_Init ends with the firmware's HAL_MspInit, if it has one. */
HAL_StatusTypeDef HAL_InitTick(uint32_t TickPriority);
void HAL_MspInit(void);
void HAL_IncTick(void);
#define TICK_INT_PRIORITY 15U

/* The NVIC (priority group 4: four bits of preemption priority, no subpriority). */
void HAL_NVIC_SetPriority(IRQn_Type IRQn, uint32_t PreemptPriority, uint32_t SubPriority);
void HAL_NVIC_EnableIRQ(IRQn_Type IRQn);
void HAL_NVIC_DisableIRQ(IRQn_Type IRQn);
void HAL_NVIC_SystemReset(void);

/* Interrupt- and DMA-driven transfers. The USART's IRQ handler (USARTx_IRQHandler, the
 * SDK's own unless the firmware defines one) calls HAL_UART_IRQHandler; the DMA streams are
 * RM0383's request mapping (USART2: DMA1 stream 6 TX, stream 5 RX, channel 4; USART1: DMA2
 * stream 7 TX, stream 2 RX, channel 4; USART6: DMA2 stream 6 TX, stream 1 RX, channel 5),
 * so no DMA handle is linked by hand. Completion calls the weak callbacks below. */
HAL_StatusTypeDef HAL_UART_Transmit_IT(UART_HandleTypeDef *huart, const uint8_t *pData,
                                       uint16_t Size);
HAL_StatusTypeDef HAL_UART_Receive_IT(UART_HandleTypeDef *huart, uint8_t *pData,
                                      uint16_t Size);
HAL_StatusTypeDef HAL_UART_Transmit_DMA(UART_HandleTypeDef *huart, const uint8_t *pData,
                                        uint16_t Size);
HAL_StatusTypeDef HAL_UART_Receive_DMA(UART_HandleTypeDef *huart, uint8_t *pData,
                                       uint16_t Size);
HAL_StatusTypeDef HAL_UART_AbortReceive(UART_HandleTypeDef *huart);
void HAL_UART_IRQHandler(UART_HandleTypeDef *huart);
void HAL_UART_MspInit(UART_HandleTypeDef *huart);
void HAL_UART_TxCpltCallback(UART_HandleTypeDef *huart);
void HAL_UART_RxCpltCallback(UART_HandleTypeDef *huart);
void HAL_UART_ErrorCallback(UART_HandleTypeDef *huart);

#define __HAL_RCC_GPIOA_CLK_ENABLE() hx_rcc_enable(&RCC->AHB1ENR, RCC_AHB1ENR_GPIOAEN)
#define __HAL_RCC_GPIOB_CLK_ENABLE() hx_rcc_enable(&RCC->AHB1ENR, RCC_AHB1ENR_GPIOBEN)
#define __HAL_RCC_GPIOC_CLK_ENABLE() hx_rcc_enable(&RCC->AHB1ENR, RCC_AHB1ENR_GPIOCEN)
#define __HAL_RCC_DMA1_CLK_ENABLE() hx_rcc_enable(&RCC->AHB1ENR, RCC_AHB1ENR_DMA1EN)
#define __HAL_RCC_DMA2_CLK_ENABLE() hx_rcc_enable(&RCC->AHB1ENR, RCC_AHB1ENR_DMA2EN)
#define __HAL_RCC_USART1_CLK_ENABLE() hx_rcc_enable(&RCC->APB2ENR, RCC_APB2ENR_USART1EN)
#define __HAL_RCC_USART2_CLK_ENABLE() hx_rcc_enable(&RCC->APB1ENR, RCC_APB1ENR_USART2EN)
#define __HAL_RCC_USART6_CLK_ENABLE() hx_rcc_enable(&RCC->APB2ENR, RCC_APB2ENR_USART6EN)
#define __HAL_RCC_SYSCFG_CLK_ENABLE() hx_rcc_enable(&RCC->APB2ENR, RCC_APB2ENR_SYSCFGEN)

/* Set `bits` of an RCC enable register and read it back (RM0383: the clock is on two
 * cycles after the write; the read-back is that delay). */
static inline void hx_rcc_enable(volatile uint32_t *reg, uint32_t bits)
{
    *reg |= bits;
    (void)*reg;
}

#ifdef __cplusplus
}
#endif

#endif /* STM32F4XX_HAL_H */
