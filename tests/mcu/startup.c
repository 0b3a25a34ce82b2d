/* tests/mcu: vector table and reset for the emulator's test firmwares (not the SDK's). */
#include <stdint.h>
extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss;
int main(void);
void Reset_Handler(void) {
    uint32_t *s = &_sidata, *d = &_sdata;
    while (d < &_edata) *d++ = *s++;
    for (d = &_sbss; d < &_ebss;) *d++ = 0;
    *(volatile uint32_t *)0xE000ED88 |= 0xFu << 20;   /* CPACR: CP10, CP11 full access */
    main();
    for (;;) __asm volatile("wfi");
}
void Default_Handler(void) { for (;;) {} }
#define WEAK __attribute__((weak, alias("Default_Handler")))
void HardFault_Handler(void) WEAK;
void MemManage_Handler(void) WEAK;
void BusFault_Handler(void) WEAK;
void UsageFault_Handler(void) WEAK;
void SVC_Handler(void) WEAK;
void PendSV_Handler(void) WEAK;
void SysTick_Handler(void) WEAK;
void EXTI0_IRQHandler(void) WEAK;
void TIM2_IRQHandler(void) WEAK;
void TIM1_UP_TIM10_IRQHandler(void) WEAK;
void TIM1_CC_IRQHandler(void) WEAK;
void USART2_IRQHandler(void) WEAK;
void DMA1_Stream5_IRQHandler(void) WEAK;
void DMA1_Stream6_IRQHandler(void) WEAK;
void CAN1_RX0_IRQHandler(void) WEAK;
void FLASH_IRQHandler(void) WEAK;
__attribute__((section(".isr_vector"), used))
void (*const vectors[16 + 86])(void) = {
    (void (*)(void))&_estack, Reset_Handler, Default_Handler, HardFault_Handler,
    MemManage_Handler, BusFault_Handler, UsageFault_Handler, 0, 0, 0, 0, SVC_Handler,
    Default_Handler, 0, PendSV_Handler, SysTick_Handler,
    [16 + 4] = FLASH_IRQHandler, [16 + 6] = EXTI0_IRQHandler, [16 + 16] = DMA1_Stream5_IRQHandler,
    [16 + 17] = DMA1_Stream6_IRQHandler, [16 + 20] = CAN1_RX0_IRQHandler,
    [16 + 25] = TIM1_UP_TIM10_IRQHandler, [16 + 27] = TIM1_CC_IRQHandler,
    [16 + 28] = TIM2_IRQHandler, [16 + 38] = USART2_IRQHandler,
};
