/* HAL_Init, HAL_GetTick, HAL_Delay over the board's virtual time (hal_board.c): every
 * HAL_GetTick is a busy-wait poll and costs the board's quantum; HAL_Delay sleeps through
 * the host. */
#include "stm32f4xx_hal.h"
#include "hal_board.h"

HAL_StatusTypeDef HAL_Init(void)
{
    hx_board_start();
    return HAL_OK;
}

uint32_t HAL_GetTick(void)
{
    hx_board_poll();
    return (uint32_t)(hx_now_us / 1000u);
}

void HAL_Delay(uint32_t Delay)
{
    uint64_t wait_ms = Delay;
    if (Delay < HAL_MAX_DELAY)
        wait_ms += 1;   /* Cube's HAL_Delay waits at least one tick more than asked */
    hx_count.cycles++;
    hx_board_sleep(hx_now_us + wait_ms * 1000u);
    hx_board_active();
}
