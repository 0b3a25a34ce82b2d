/* A firmware that enables an interrupt it has no handler for: TIM3's (IRQ 29), pended by
 * hand (no TIM3_IRQHandler here). The startup's Default_Handler takes it and branches to
 * itself for ever at the interrupt's priority 0, which SysTick (priority 15) cannot
 * preempt: on the board a hang. The run must end in one line naming the lockup, the PC and Default_Handler. */
#include "stm32f4xx_hal.h"

#include <stdio.h>

int main(void)
{
    HAL_Init();
    printf("unhandled: enabling TIM3_IRQn\n");
    HAL_Delay(5);
    HAL_NVIC_EnableIRQ(TIM3_IRQn);
    NVIC->ISPR[0] = 1u << TIM3_IRQn;
    printf("unhandled: still running\n");
    for (;;)
        __WFI();
}
