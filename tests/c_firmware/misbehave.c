/* A firmware that walks in place for 0.2 s of virtual time, then misbehaves as its
 * build's MODE says: 1 segfaults, 2 hangs without a HAL call, 3 returns from main early
 * (tests/test_c_sdk.py: each is one line and a non-zero exit, the trace kept). */
#include "stm32f4xx_hal.h"

#include <signal.h>

#ifndef MODE
#error "build with -DMODE=1 (crash), 2 (hang) or 3 (early exit)"
#endif

int main(void)
{
    HAL_Init();
    while (HAL_GetTick() < 200)
        HAL_Delay(19);
    if (MODE == 1)
        raise(SIGSEGV);
    if (MODE == 2)
        for (volatile int spin = 1; spin;) {
        }
    return 0;
}
