/* The STM32Cube HAL subset a Dynamixel hexapod firmware uses (hexhil_hal_api.h), for the
 * host: served in virtual time over the hexhil firmware link (docs/link.md,
 * docs/c-firmware.md). A port and a USART are a name here, registers on the board
 * (stm32f411/include/stm32f4xx_hal.h). */
#ifndef STM32F4XX_HAL_H
#define STM32F4XX_HAL_H

#include "hexhil_hal_api.h"

#ifdef __cplusplus
extern "C" {
#endif

struct hx_gpio_port {
    uint32_t id;          /* the port's letter, 'A', 'B', ... (registers on the board) */
};

extern GPIO_TypeDef hexhil_gpioa, hexhil_gpiob, hexhil_gpioc;
#define GPIOA (&hexhil_gpioa)
#define GPIOB (&hexhil_gpiob)
#define GPIOC (&hexhil_gpioc)

struct hx_usart {
    uint32_t id;          /* the USART's number (registers on the board) */
};

extern USART_TypeDef hexhil_usart1, hexhil_usart2, hexhil_usart6;
#define USART1 (&hexhil_usart1)
#define USART2 (&hexhil_usart2)
#define USART6 (&hexhil_usart6)

struct __UART_HandleTypeDef {
    USART_TypeDef *Instance;
    UART_InitTypeDef Init;
    volatile HAL_UART_StateTypeDef gState;
    volatile uint32_t ErrorCode;
    uint32_t halfduplex;  /* set by HAL_HalfDuplex_Init */
    uint32_t te, re;      /* transmitter and receiver enabled (CR1 TE, RE) */
};

#define __HAL_RCC_GPIOA_CLK_ENABLE() do { } while (0)
#define __HAL_RCC_GPIOB_CLK_ENABLE() do { } while (0)
#define __HAL_RCC_GPIOC_CLK_ENABLE() do { } while (0)
#define __HAL_RCC_USART1_CLK_ENABLE() do { } while (0)
#define __HAL_RCC_USART2_CLK_ENABLE() do { } while (0)
#define __HAL_RCC_USART6_CLK_ENABLE() do { } while (0)

#ifdef __cplusplus
}
#endif

#endif /* STM32F4XX_HAL_H */
