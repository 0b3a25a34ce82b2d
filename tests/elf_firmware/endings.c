/* A firmware that ends as a host program would, built as a CubeMX user builds one
 * (newlib-nano, --specs=nano.specs --specs=nosys.specs): after a console line and 20 ms it
 * calls exit(EXIT_STATUS) (newlib's exit reaches libnosys's `_exit`, a loop on the chip),
 * or abort(), or fails an assert, or returns from main, or spins as CubeMX's Error_Handler
 * does (interrupts masked, an endless loop), or as FreeRTOS's configASSERT does (BASEPRI),
 * or leaves an interrupt to the startup's Default_Handler below SysTick's priority, or
 * calls HAL_Delay in an interrupt that SysTick (at CubeMX's tick priority, 15) cannot
 * preempt. The ending is chosen with -DEND=... */
#include "stm32f4xx_hal.h"

#include <assert.h>
#include <stdio.h>
#include <stdlib.h>

#define END_EXIT 1
#define END_ABORT 2
#define END_ASSERT 3
#define END_RETURN 4
#define END_ERROR_HANDLER 5
#define END_NONE 6
#define END_HANDLER_LOOP 7   /* TIM3 pended without a handler, below SysTick: Default_Handler */
#define END_RTOS_ASSERT 8    /* FreeRTOS's configASSERT: BASEPRI raised, an endless loop */
#define END_ISR_DELAY 9      /* HAL_Delay(5) in TIM3's handler at priority 0: no tick comes */
#ifndef EXIT_STATUS
#define EXIT_STATUS 3
#endif

volatile int servos_found;   /* 0: the assertion below fails */

__attribute__((noinline)) void Error_Handler(void)   /* called from many places in a CubeMX project */
{
    __disable_irq();
    while (1) {
    }
}

#if END == END_ISR_DELAY
void TIM3_IRQHandler(void)
{
    HAL_Delay(5);
    printf("endings: never here\n");
}
#endif

int main(void)
{
    HAL_Init();
    printf("endings: start\n");
    HAL_Delay(20);
#if END == END_EXIT
    exit(EXIT_STATUS);
#elif END == END_ABORT
    abort();
#elif END == END_ASSERT
    assert(servos_found == 18);
#elif END == END_RETURN
    return EXIT_STATUS;
#elif END == END_ERROR_HANDLER
    Error_Handler();
#elif END == END_RTOS_ASSERT
    __asm volatile("msr basepri, %0" : : "r"(5u << 4) : "memory");
    for (;;) {
    }
#elif END == END_HANDLER_LOOP
    HAL_NVIC_SetPriority(SysTick_IRQn, 0, 0);
    HAL_NVIC_SetPriority(TIM3_IRQn, 15, 0);
    HAL_NVIC_EnableIRQ(TIM3_IRQn);
    NVIC->ISPR[0] = 1u << TIM3_IRQn;
#elif END == END_ISR_DELAY
    HAL_NVIC_SetPriority(TIM3_IRQn, 0, 0);
    HAL_NVIC_EnableIRQ(TIM3_IRQn);
    NVIC->ISPR[0] = 1u << TIM3_IRQn;
#endif
    for (;;)
        __WFI();
}
