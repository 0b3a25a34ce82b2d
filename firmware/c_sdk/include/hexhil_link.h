/* The hexhil firmware link, version 1 (docs/link.md), for a C client: TCP on 127.0.0.1 at
 * the port in HEXHIL_LINK_PORT. Posted messages (W, C, E) are queued and go out in the same
 * write as the next request. A link error (an error reply, a closed link, a broken limit)
 * is reported in one line on stderr ("hexhil link: ...") and the process exits 2. */
#ifndef HEXHIL_LINK_H
#define HEXHIL_LINK_H

#include <stdint.h>

#define HX_LINK_VERSION 1
#define HX_OP_HELLO 0x48
#define HX_OP_TRANSACT 0x58
#define HX_OP_SLEEP 0x53
#define HX_OP_MORE 0x4D
#define HX_OP_WRITE 0x57
#define HX_OP_CAN 0x43
#define HX_OP_EVENT 0x45
#define HX_OP_BAUD 0x42
#define HX_FLAG_END 0x01
#define HX_FLAG_MORE 0x02
#define HX_EVENT_LOG 0
#define HX_EVENT_EXCEPTION 1
#define HX_EVENT_STOP 2
#define HX_EVENT_STATS 3
#define HX_EVENT_TACTILE 4
#define HX_EVENT_FAULT 5
#define HX_MAX_REPLY_LEN 2048
#define HX_MAX_RX_LEN (HX_MAX_REPLY_LEN - 8)

/* Connect and say hello as `runtime`; the config JSON of the hello reply is kept. */
void hx_link_open(const char *runtime);
int hx_link_is_open(void);
const char *hx_link_config(void);      /* the hello reply's config JSON ("" if none) */
uint64_t hx_link_t_us(void);           /* virtual time of the last reply */
uint8_t hx_link_switches(void);        /* bit i: leg i's switch pressed, at the last reply */

/* Posted messages: queued until the next request. */
void hx_link_post(uint8_t op, const void *payload, uint16_t n);
void hx_link_event(uint8_t kind, const char *text);
void hx_link_can_send(uint16_t id, const uint8_t *data, uint8_t dlc);
void hx_link_baud(uint32_t bps);     /* the servo UART's rate: the host's line runs at it */

/* Requests: one round trip each. */
uint16_t hx_link_transact(const uint8_t *tx, uint16_t ntx, uint8_t *rx, uint16_t nrx,
                          uint32_t timeout_us);   /* bytes received (fewer: time-out) */
uint8_t hx_link_sleep(uint64_t wake_us);  /* the reply's flags (FLAG_END: the run is over);
                                             every CAN frame of the sleep is queued */
int hx_link_can_recv(uint16_t *id, uint8_t data[8], uint8_t *dlc);  /* 1: a frame taken */

/* Send what is queued and close the link (the run is over). */
void hx_link_close(void);

#endif /* HEXHIL_LINK_H */
