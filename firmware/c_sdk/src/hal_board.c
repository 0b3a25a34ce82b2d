/* The board core: the virtual board's clock and the busy-wait rule, its counters and
 * faults, the direction line's level and the servo line's held bytes. Every HAL call that
 * costs time or touches the line comes here (hal_gpio.c, hal_tick.c, hal_uart.c); this
 * file calls only the link (hexhil_link.c).
 *
 * Every poll costs HX_QUANTUM_US, so a loop that polls the tick or a switch moves virtual
 * time as it would on the board; once the board's clock is HX_SYNC_US ahead of the host's
 * it sleeps there (the switches and the run's end arrive). A firmware that only polls for
 * HX_HANG_US (no UART write or read, direction turn or delay) is hung: one line on stderr,
 * exit 2. At the run's end the stats go to the host and the process exits 0
 * (docs/c-firmware.md). Line bytes are held and sent with the next receive (one transact)
 * or before the next sleep (a posted write). */
#include "hal_board.h"
#include "hexhil_link.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

uint64_t hx_now_us;
struct hx_counters hx_count;
static uint64_t quiet_since_us;   /* the board's time of its last activity */
static uint64_t slept_us;         /* the board's time of its last sleep */
static int direction_tx;          /* PA1 high */
static uint8_t held[HX_LINE_HOLD];
static uint16_t held_len;

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

/* Held bytes go out as a posted write (before a sleep, or when the hold is full). */
static void flush_line(void)
{
    if (held_len) {
        hx_link_post(HX_OP_WRITE, held, held_len);
        hx_count.writes++;
        held_len = 0;
    }
}

void hx_board_sleep(uint64_t wake_us)
{
    hx_board_start();
    flush_line();
    uint8_t flags = hx_link_sleep(wake_us);
    hx_board_synced();
    slept_us = hx_now_us;
    if (flags & HX_FLAG_END)
        finish();
}

void hx_board_baud(uint32_t bps)
{
    hx_link_baud(bps);
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

void hx_direction_set(int tx)
{
    hx_board_active();
    direction_tx = tx;
}

int hx_direction_tx(void)
{
    return direction_tx;
}

void hx_line_hold(const uint8_t *data, uint16_t n)
{
    if (held_len + n > sizeof held)
        flush_line();
    memcpy(held + held_len, data, n);
    held_len += n;
}

uint16_t hx_line_transact(uint8_t *rx, uint16_t want, uint32_t timeout_us)
{
    uint16_t got = hx_link_transact(held, held_len, rx, want, timeout_us);
    held_len = 0;
    hx_count.transactions++;
    hx_board_synced();
    return got;
}
