/* A firmware that misbehaves as its build's MODE says (tests/test_c_sdk.py): after
 * walking in place for 0.2 s of virtual time, 1 segfaults, 2 hangs without a HAL call,
 * 3 returns from main early, 6 polls the tick for ever (a hang in virtual time); 4 exits
 * before it connects; 5 prints 1 MB on stdout and then runs to the end (it must not block
 * on the pipe). */
#include "stm32f4xx_hal.h"

#include <signal.h>
#include <stdio.h>

#ifndef MODE
#error "build with -DMODE=1 (crash), 2 (hang), 3 (early exit), 4 (no link), 5 (chatty), 6 (polls)"
#endif

int main(void)
{
    if (MODE == 4) {
        fprintf(stderr, "no board here\n");
        return 1;
    }
    HAL_Init();
    if (MODE == 5)
        for (int i = 0; i < 16384; i++)
            printf("%063d\n", i);
    while (MODE == 5 || HAL_GetTick() < 200)
        HAL_Delay(19);
    if (MODE == 1)
        raise(SIGSEGV);
    if (MODE == 2)
        for (volatile int spin = 1; spin;) {
        }
    while (MODE == 6)
        HAL_GetTick();
    return 0;
}
