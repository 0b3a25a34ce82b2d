/* The SDK's register definitions against RM0383's register maps: every offset and base
 * address below is a row of the manual's tables; a wrong one fails the build. */
#include "stm32f4xx_hal.h"

#include <stddef.h>

#define AT(type, reg, offset) _Static_assert(offsetof(type, reg) == (offset), #type "." #reg)

AT(RCC_TypeDef, PLLCFGR, 0x04); AT(RCC_TypeDef, CFGR, 0x08); AT(RCC_TypeDef, AHB1ENR, 0x30);
AT(RCC_TypeDef, APB1ENR, 0x40); AT(RCC_TypeDef, APB2ENR, 0x44); AT(RCC_TypeDef, BDCR, 0x70);
AT(RCC_TypeDef, DCKCFGR, 0x8C);
AT(GPIO_TypeDef, PUPDR, 0x0C); AT(GPIO_TypeDef, IDR, 0x10); AT(GPIO_TypeDef, BSRR, 0x18);
AT(GPIO_TypeDef, AFR, 0x20);
AT(USART_TypeDef, DR, 0x04); AT(USART_TypeDef, BRR, 0x08); AT(USART_TypeDef, CR1, 0x0C);
AT(USART_TypeDef, CR3, 0x14);
AT(DMA_TypeDef, HIFCR, 0x0C); AT(DMA_TypeDef, S[5].CR, 0x10 + 0x18 * 5);
AT(DMA_Stream_TypeDef, FCR, 0x14);
AT(EXTI_TypeDef, PR, 0x14); AT(SYSCFG_TypeDef, EXTICR, 0x08); AT(SYSCFG_TypeDef, CMPCR, 0x20);
AT(TIM_TypeDef, CNT, 0x24); AT(TIM_TypeDef, ARR, 0x2C); AT(TIM_TypeDef, CCR1, 0x34);
AT(TIM_TypeDef, OR, 0x50);
AT(CAN_TypeDef, BTR, 0x1C); AT(CAN_TypeDef, TX[0].TIR, 0x180); AT(CAN_TypeDef, RX[0].RIR, 0x1B0);
AT(CAN_TypeDef, FMR, 0x200); AT(CAN_TypeDef, FA1R, 0x21C); AT(CAN_TypeDef, FILTER, 0x240);
AT(NVIC_TypeDef, ICER, 0x80); AT(NVIC_TypeDef, ISPR, 0x100); AT(NVIC_TypeDef, IPR, 0x300);
AT(SCB_TypeDef, VTOR, 0x08); AT(SCB_TypeDef, SHPR, 0x18); AT(SCB_TypeDef, CFSR, 0x28);
AT(SysTick_TypeDef, CVR, 0x08);

_Static_assert(RCC_BASE == 0x40023800u && FLASH_R_BASE == 0x40023C00u, "RCC, FLASH");
_Static_assert(GPIOB_BASE == 0x40020400u && USART2_BASE == 0x40004400u, "GPIOB, USART2");
_Static_assert(USART1_BASE == 0x40011000u && USART6_BASE == 0x40011400u, "USART1, USART6");
_Static_assert(DMA1_BASE == 0x40026000u && DMA2_BASE == 0x40026400u, "DMA");
_Static_assert(EXTI_BASE == 0x40013C00u && SYSCFG_BASE == 0x40013800u, "EXTI, SYSCFG");
_Static_assert(TIM5_BASE == 0x40000C00u && PWR_BASE == 0x40007000u, "TIM5, PWR");
_Static_assert(CAN1_BASE == 0x40006400u, "bxCAN1 where the F405 has it");
_Static_assert(DMA_FLAG_SHIFT(5) == 6 && DMA_FLAG_SHIFT(6) == 16 && DMA_FLAG_SHIFT(7) == 22,
               "a stream's flags in HISR");

int main(void)
{
    return 0;
}
