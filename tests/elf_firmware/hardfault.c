/* A firmware that faults: after a console line it calls fault_here, which executes an
 * undefined instruction (UDF). On the board that is a UsageFault escalated to HardFault;
 * the run must end in one line naming the fault, the PC and fault_here. */
#include "stm32f4xx_hal.h"

#include <stdio.h>

__attribute__((noinline)) int fault_here(int x)
{
    if (x > 0)
        __builtin_trap();
    return x;
}

int main(void)
{
    HAL_Init();
    printf("hardfault: about to fault\n");
    HAL_Delay(10);
    volatile int x = 3;
    fault_here(x);
    printf("hardfault: still running\n");
    for (;;)
        __WFI();
}
