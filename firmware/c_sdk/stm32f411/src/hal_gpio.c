/* HAL_GPIO_* on the F411's ports (RM0383 section 8): MODER, OTYPER, OSPEEDR, PUPDR and AFR
 * per pin from GPIO_InitTypeDef; levels through IDR and the atomic BSRR; a pin in an
 * interrupt mode is routed to its EXTI line by SYSCFG_EXTICR with the edges asked for
 * (RM0383 sections 7 and 10). */
#include "stm32f4xx_hal.h"

#define MODE_EXTI    0x10000000u   /* Cube's mode code: an interrupt (EXTI) mode */
#define MODE_RISING  0x00100000u
#define MODE_FALLING 0x00200000u

static void route_exti(const GPIO_TypeDef *port, uint32_t pin, uint32_t mode)
{
    uint32_t index = ((uint32_t)(uintptr_t)port - GPIOA_BASE) / 0x400u;   /* A = 0, B = 1 */
    uint32_t four = (pin & 3u) * 4u, bit = 1u << pin;
    hx_rcc_enable(&RCC->APB2ENR, RCC_APB2ENR_SYSCFGEN);
    SYSCFG->EXTICR[pin >> 2] = (SYSCFG->EXTICR[pin >> 2] & ~(0xFu << four)) | (index << four);
    EXTI->RTSR = (mode & MODE_RISING) ? EXTI->RTSR | bit : EXTI->RTSR & ~bit;
    EXTI->FTSR = (mode & MODE_FALLING) ? EXTI->FTSR | bit : EXTI->FTSR & ~bit;
    EXTI->IMR |= bit;
}

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
        if (GPIO_Init->Mode & MODE_EXTI)
            route_exti(GPIOx, pin, GPIO_Init->Mode);
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

void __weak HAL_GPIO_EXTI_Callback(uint16_t GPIO_Pin) { (void)GPIO_Pin; }

void HAL_GPIO_EXTI_IRQHandler(uint16_t GPIO_Pin)
{
    if (EXTI->PR & GPIO_Pin) {
        EXTI->PR = GPIO_Pin;   /* cleared by writing 1 */
        HAL_GPIO_EXTI_Callback(GPIO_Pin);
    }
}

/* Lines first..last share one IRQ: each pending one in turn. */
static void exti_lines(uint32_t first, uint32_t last)
{
    for (uint32_t line = first; line <= last; line++)
        HAL_GPIO_EXTI_IRQHandler((uint16_t)(1u << line));
}

void __weak EXTI0_IRQHandler(void) { exti_lines(0, 0); }
void __weak EXTI1_IRQHandler(void) { exti_lines(1, 1); }
void __weak EXTI2_IRQHandler(void) { exti_lines(2, 2); }
void __weak EXTI3_IRQHandler(void) { exti_lines(3, 3); }
void __weak EXTI4_IRQHandler(void) { exti_lines(4, 4); }
void __weak EXTI9_5_IRQHandler(void) { exti_lines(5, 9); }
void __weak EXTI15_10_IRQHandler(void) { exti_lines(10, 15); }
