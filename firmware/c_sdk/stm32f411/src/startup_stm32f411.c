/* The F411's reset: the vector table at the start of flash (RM0383 Table 37: 16 system
 * entries, then 86 device interrupts), and Reset_Handler, which enables the FPU, copies
 * .data from flash, zeroes .bss, runs SystemInit (the 100 MHz clock tree), the C library's
 * constructors and main. Every handler is weak: a firmware's own SysTick_Handler,
 * USART2_IRQHandler or HardFault_Handler takes the place of this file's (or of the HAL's, for
 * SysTick, EXTI, the USARTs and their DMA streams). An interrupt with no handler lands in
 * Default_Handler, a loop that keeps the fault visible to a debugger (and to hexhil's
 * emulator, which names the PC and the function). The symbols come from stm32f411.ld. */
#include "stm32f411xe.h"

extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss;
extern int main(void);
extern void __libc_init_array(void);
void SystemInit(void);
void Reset_Handler(void);
/* The SDK's own, weak in hal_core.c, hal_gpio.c and hal_uart.c (a firmware's wins). */
void SysTick_Handler(void), USART1_IRQHandler(void), USART2_IRQHandler(void);
void USART6_IRQHandler(void), DMA1_Stream5_IRQHandler(void), DMA1_Stream6_IRQHandler(void);
void DMA2_Stream1_IRQHandler(void), DMA2_Stream2_IRQHandler(void);
void DMA2_Stream6_IRQHandler(void), DMA2_Stream7_IRQHandler(void);
void EXTI0_IRQHandler(void), EXTI1_IRQHandler(void), EXTI2_IRQHandler(void);
void EXTI3_IRQHandler(void), EXTI4_IRQHandler(void), EXTI9_5_IRQHandler(void);
void EXTI15_10_IRQHandler(void);

void Default_Handler(void)
{
    for (;;) {
    }
}

#define SYSTEM(name) void name(void) __attribute__((weak, alias("Default_Handler")));
SYSTEM(NMI_Handler) SYSTEM(HardFault_Handler) SYSTEM(MemManage_Handler)
SYSTEM(BusFault_Handler) SYSTEM(UsageFault_Handler) SYSTEM(SVC_Handler)
SYSTEM(DebugMon_Handler) SYSTEM(PendSV_Handler)

#define IRQ(name) void name##_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
IRQ(WWDG) IRQ(PVD) IRQ(TAMP_STAMP) IRQ(RTC_WKUP) IRQ(FLASH) IRQ(RCC) IRQ(DMA1_Stream0)
IRQ(DMA1_Stream1) IRQ(DMA1_Stream2) IRQ(DMA1_Stream3) IRQ(DMA1_Stream4) IRQ(ADC)
IRQ(CAN1_TX) IRQ(CAN1_RX0) IRQ(CAN1_RX1) IRQ(CAN1_SCE) IRQ(TIM1_BRK_TIM9)
IRQ(TIM1_UP_TIM10) IRQ(TIM1_TRG_COM_TIM11) IRQ(TIM1_CC) IRQ(TIM2) IRQ(TIM3) IRQ(TIM4)
IRQ(I2C1_EV) IRQ(I2C1_ER) IRQ(I2C2_EV) IRQ(I2C2_ER) IRQ(SPI1) IRQ(SPI2) IRQ(RTC_Alarm)
IRQ(OTG_FS_WKUP) IRQ(DMA1_Stream7) IRQ(SDIO) IRQ(TIM5) IRQ(SPI3) IRQ(DMA2_Stream0)
IRQ(DMA2_Stream3) IRQ(DMA2_Stream4) IRQ(OTG_FS) IRQ(DMA2_Stream5) IRQ(I2C3_EV)
IRQ(I2C3_ER) IRQ(FPU) IRQ(SPI4) IRQ(SPI5)

typedef void (*vector_t)(void);

/* Position 0 is the initial stack pointer; the hardware loads it before Reset_Handler. */
__attribute__((section(".isr_vector"), used))
const vector_t hx_vector_table[16 + 86] = {
    (vector_t)(uintptr_t)&_estack, Reset_Handler, NMI_Handler, HardFault_Handler,
    MemManage_Handler, BusFault_Handler, UsageFault_Handler, 0, 0, 0, 0,
    SVC_Handler, DebugMon_Handler, 0, PendSV_Handler, SysTick_Handler,
#define H(name) name##_IRQHandler
    /*  0 */ H(WWDG), H(PVD), H(TAMP_STAMP), H(RTC_WKUP), H(FLASH), H(RCC),
    /*  6 */ H(EXTI0), H(EXTI1), H(EXTI2), H(EXTI3), H(EXTI4), H(DMA1_Stream0),
    /* 12 */ H(DMA1_Stream1), H(DMA1_Stream2), H(DMA1_Stream3), H(DMA1_Stream4),
    /* 16 */ H(DMA1_Stream5), H(DMA1_Stream6),
    /* 18 */ H(ADC), H(CAN1_TX), H(CAN1_RX0), H(CAN1_RX1), H(CAN1_SCE), H(EXTI9_5),
    /* 24 */ H(TIM1_BRK_TIM9), H(TIM1_UP_TIM10), H(TIM1_TRG_COM_TIM11), H(TIM1_CC),
    /* 28 */ H(TIM2), H(TIM3),
    /* 30 */ H(TIM4), H(I2C1_EV), H(I2C1_ER), H(I2C2_EV), H(I2C2_ER), H(SPI1),
    /* 36 */ H(SPI2), H(USART1), H(USART2), 0, H(EXTI15_10), H(RTC_Alarm),
    /* 42 */ H(OTG_FS_WKUP), 0, 0, 0, 0, H(DMA1_Stream7),
    /* 48 */ 0, H(SDIO), H(TIM5), H(SPI3), 0, 0,
    /* 54 */ 0, 0, H(DMA2_Stream0), H(DMA2_Stream1), H(DMA2_Stream2), H(DMA2_Stream3),
    /* 60 */ H(DMA2_Stream4), 0, 0, 0, 0, 0,
    /* 66 */ 0, H(OTG_FS), H(DMA2_Stream5), H(DMA2_Stream6), H(DMA2_Stream7), H(USART6),
    /* 72 */ H(I2C3_EV), H(I2C3_ER), 0, 0, 0, 0,
    /* 78 */ 0, 0, 0, H(FPU), 0, 0,
    /* 84 */ H(SPI4), H(SPI5),
};

void Reset_Handler(void)
{
    SCB_CPACR |= 0xFu << 20;   /* CP10 and CP11: full access, before any FPU instruction */
    __DSB();
    __ISB();
    uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;)
        *dst++ = *src++;
    for (uint32_t *dst = &_sbss; dst < &_ebss;)
        *dst++ = 0;
    SystemInit();
    __libc_init_array();
    main();
    for (;;) {   /* main returned: idle until the run (or the board's power) ends */
        __WFI();
    }
}
