/* HAL_Init, HAL_GetTick, HAL_Delay over the link's virtual time, and the busy-wait rule:
 * every HAL_GetTick or HAL_GPIO_ReadPin costs HX_QUANTUM_US, so a loop that polls the tick
 * or a switch moves virtual time as it would on the board; once the board's clock is
 * HX_SYNC_US ahead of the host's it sleeps there (the switches and the run's end arrive).
 * A firmware that only polls for HX_HANG_US (no UART write or read, direction turn or
 * delay) is hung: one line on stderr, exit 2. At the run's end the stats go to the host
 * and the process exits 0 (docs/c-firmware.md). */
#include "stm32f4xx_hal.h"
#include "hal_board.h"
#include "hexhil_link.h"

#include <stdio.h>
#include <stdlib.h>

uint64_t hx_now_us;
struct hx_counters hx_count;
static uint64_t quiet_since_us;   /* the board's time of its last activity */
static uint64_t slept_us;         /* the board's time of its last sleep */

void hx_board_start(void)
{
    if (!hx_link_is_open()) {
        setvbuf(stdout, NULL, _IOLBF, 0);   /* a printed line reaches the host's trace then */
        hx_link_open("c-stm32cube");
        hx_now_us = hx_link_t_us();
    }
}

void hx_board_synced(void)
{
    if (hx_link_t_us() > hx_now_us)
        hx_now_us = hx_link_t_us();
}

static void finish(void)
{
    char stats[256];
    snprintf(stats, sizeof stats,
             "{\"cycles\": %u, \"transactions\": %u, \"sync_writes\": %u, \"timeouts\": %u}",
             hx_count.cycles, hx_count.transactions, hx_count.writes, hx_count.timeouts);
    hx_link_event(HX_EVENT_STATS, stats);
    hx_link_close();
    exit(0);
}

void hx_board_sleep(uint64_t wake_us)
{
    hx_board_start();
    hx_uart_flush();
    uint8_t flags = hx_link_sleep(wake_us);
    hx_board_synced();
    slept_us = hx_now_us;
    if (flags & HX_FLAG_END)
        finish();
}

/* Only a sleep reply carries the run's end: a firmware that never sleeps (a cycle that
 * always overruns, as at a baud no servo answers) asks with a sleep to now now and then. */
void hx_board_check_end(void)
{
    if (hx_now_us - slept_us >= HX_END_CHECK_US)
        hx_board_sleep(hx_now_us);
}

void hx_board_active(void)
{
    quiet_since_us = hx_now_us;
}

void hx_board_poll(void)
{
    hx_board_start();
    hx_now_us += HX_QUANTUM_US;
    if (hx_now_us - quiet_since_us >= HX_HANG_US) {
        fprintf(stderr, "hexhil board: hung: no UART write or read, direction turn or delay "
                "for %u virtual seconds (since t=%.6f s)\n", HX_HANG_US / 1000000u,
                (double)quiet_since_us * 1e-6);
        hx_link_close();
        exit(2);
    }
    if (hx_now_us - hx_link_t_us() >= HX_SYNC_US)
        hx_board_sleep(hx_now_us);
}

void hx_board_fault(const char *name, const char *detail)
{
    char text[256];
    snprintf(text, sizeof text, "{\"name\": \"%s\", \"detail\": \"%s\"}", name, detail);
    hx_link_event(HX_EVENT_FAULT, text);
}

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
