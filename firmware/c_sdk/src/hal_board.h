/* The board core (hal_board.c): the virtual board's clock, counters, faults, direction
 * line and the servo line's held bytes. hal_gpio.c, hal_tick.c and hal_uart.c call it; it
 * calls none of them, only the link (hexhil_link.c). */
#ifndef HAL_BOARD_H
#define HAL_BOARD_H

#include <stdint.h>

#define HX_QUANTUM_US 5        /* virtual time one busy-wait poll costs (the virtual board's) */
#define HX_SYNC_US 1000        /* a busy-wait this far ahead of the host sleeps to catch up */
#define HX_HANG_US 2000000u    /* only polls this long: hung (the virtual board's HANG_S) */
#define HX_END_CHECK_US 100000u  /* no sleep this long (every cycle overran): ask for the end */
#define HX_DIR_PORT 'A'        /* the direction line: GPIOA pin 1, high = transmit */
#define HX_DIR_PIN 0x0002u
#define HX_SWITCH_PORT 'B'     /* the leg switches: GPIOB pins 0-5, pressed = low */
#define HX_LINE_HOLD 4096      /* line bytes held until the next receive or sleep */

extern uint64_t hx_now_us;     /* the board's virtual time (never behind the host's) */

struct hx_counters {
    uint32_t cycles, transactions, writes, timeouts, tx_while_receiving, rx_while_transmitting;
};
extern struct hx_counters hx_count;

void hx_board_start(void);     /* HAL_Init: the link opened once */
void hx_board_synced(void);    /* the host answered: hx_now_us catches up with it */
void hx_board_sleep(uint64_t wake_us);  /* to wake_us through the host; exits at the end */
void hx_board_check_end(void); /* a sleep to now if none came for HX_END_CHECK_US */
void hx_board_baud(uint32_t bps);  /* USART2's rate, to the host's line */
void hx_board_poll(void);      /* one busy-wait poll (the quantum, a sleep when far ahead) */
void hx_board_active(void);    /* a UART write or read, a direction turn, a delay: not hung */
void hx_board_fault(const char *name, const char *detail);
void hx_direction_set(int tx); /* the direction pin's level (hal_gpio.c writes it) */
int hx_direction_tx(void);     /* the direction pin is high */
void hx_line_hold(const uint8_t *data, uint16_t n);   /* bytes for the line, held */
uint16_t hx_line_transact(uint8_t *rx, uint16_t want, uint32_t timeout_us);
                               /* the held bytes out, then up to want status bytes */

#endif
