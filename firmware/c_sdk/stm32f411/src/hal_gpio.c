/* HAL_GPIO_* on the F411's ports (RM0383 section 8): MODER, OTYPER, OSPEEDR, PUPDR and AFR
 * per pin from GPIO_InitTypeDef; levels through IDR and the atomic BSRR. */
#include "stm32f4xx_hal.h"

void HAL_GPIO_Init(GPIO_TypeDef *GPIOx, GPIO_InitTypeDef *GPIO_Init)
{
    uint32_t mode = GPIO_Init->Mode & 3u;
    for (uint32_t pin = 0; pin < 16u; pin++) {
        if (!(GPIO_Init->Pin & (1u << pin)))
            continue;
        uint32_t two = pin * 2u;
        if (mode == GPIO_MODE_AF_PP) {
            volatile uint32_t *afr = &GPIOx->AFR[pin >> 3];
            uint32_t four = (pin & 7u) * 4u;
            *afr = (*afr & ~(0xFu << four)) | ((GPIO_Init->Alternate & 0xFu) << four);
        }
        if (mode == GPIO_MODE_OUTPUT_PP || mode == GPIO_MODE_AF_PP) {
            GPIOx->OSPEEDR = (GPIOx->OSPEEDR & ~(3u << two)) | ((GPIO_Init->Speed & 3u) << two);
            GPIOx->OTYPER = (GPIOx->OTYPER & ~(1u << pin)) |
                            (((GPIO_Init->Mode >> 4) & 1u) << pin);
        }
        GPIOx->PUPDR = (GPIOx->PUPDR & ~(3u << two)) | ((GPIO_Init->Pull & 3u) << two);
        GPIOx->MODER = (GPIOx->MODER & ~(3u << two)) | (mode << two);
    }
}

GPIO_PinState HAL_GPIO_ReadPin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin)
{
    return (GPIOx->IDR & GPIO_Pin) ? GPIO_PIN_SET : GPIO_PIN_RESET;
}

void HAL_GPIO_WritePin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin, GPIO_PinState PinState)
{
    GPIOx->BSRR = PinState != GPIO_PIN_RESET ? GPIO_Pin : (uint32_t)GPIO_Pin << 16;
}

void HAL_GPIO_TogglePin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin)
{
    uint32_t odr = GPIOx->ODR;
    GPIOx->BSRR = ((odr & GPIO_Pin) << 16) | (~odr & GPIO_Pin);
}
