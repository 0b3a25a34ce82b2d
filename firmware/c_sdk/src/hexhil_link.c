/* The firmware link, version 1, client side over a POSIX socket (docs/link.md): framing,
 * the posted-message queue and the CAN frames of sleep replies. */
#define _POSIX_C_SOURCE 200809L
#include "hexhil_link.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define SEND_CAP 65536          /* posted messages beyond this go out early (in order) */
#define CAN_RING 4096           /* CAN frames held for hx_link_can_recv */

static int sock = -1;
static uint8_t out[SEND_CAP + 3 + 65535];
static size_t out_len;
static uint8_t reply[HX_MAX_REPLY_LEN];
static char config[HX_MAX_REPLY_LEN + 1];
static uint64_t t_us;
static uint8_t switches;

static struct { uint16_t id; uint8_t dlc; uint8_t data[8]; } ring[CAN_RING];
static unsigned ring_head, ring_count;

static void fail(const char *text)
{
    fprintf(stderr, "hexhil link: %s\n", text);
    exit(2);
}

static void put_u16(uint8_t *p, uint16_t v) { p[0] = v & 0xFF; p[1] = v >> 8; }

static uint64_t get_u64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | p[i];
    return v;
}

static void flush(void)
{
    size_t done = 0;
    while (done < out_len) {
        ssize_t n = send(sock, out + done, out_len - done, 0);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            fail("the simulator closed the link");
        done += (size_t)n;
    }
    out_len = 0;
}

static void read_all(uint8_t *p, size_t n)
{
    while (n) {
        ssize_t got = recv(sock, p, n, 0);
        if (got < 0 && errno == EINTR)
            continue;
        if (got <= 0)
            fail("the simulator closed the link");
        p += got;
        n -= (size_t)got;
    }
}

static void queue(uint8_t op, const void *payload, uint16_t n)
{
    if (out_len + 3 + n > sizeof out || out_len > SEND_CAP)
        flush();
    out[out_len] = op;
    put_u16(out + out_len + 1, n);
    if (n)
        memcpy(out + out_len + 3, payload, n);
    out_len += 3 + (size_t)n;
}

/* Send the queue with a request; the reply's body length (after t_us) in `reply + 8`. */
static size_t request(uint8_t op, const void *payload, uint16_t n)
{
    uint8_t head[2];
    queue(op, payload, n);
    flush();
    read_all(head, 2);
    size_t len = head[0] | (head[1] << 8);
    if (len < 8 || len > HX_MAX_REPLY_LEN)
        fail("broken link: a reply's length is out of range");
    read_all(reply, len);
    uint64_t t = get_u64(reply);
    if (t == UINT64_MAX) {
        char text[HX_MAX_REPLY_LEN];
        size_t m = len - 8;
        memcpy(text, reply + 8, m);
        text[m] = 0;
        char *nl = strchr(text, '\n');
        if (nl)
            *nl = 0;
        fail(text);
    }
    t_us = t;
    return len - 8;
}

/* A payload of one byte and then text, cut to `cap`; its length. */
static uint16_t byte_and_text(uint8_t *buf, size_t cap, uint8_t first, const char *text)
{
    size_t n = strlen(text);
    if (n > cap - 1)
        n = cap - 1;
    buf[0] = first;
    memcpy(buf + 1, text, n);
    return (uint16_t)(n + 1);
}

void hx_link_open(const char *runtime)
{
    const char *port = getenv("HEXHIL_LINK_PORT");
    char *end;
    long p = port ? strtol(port, &end, 10) : 0;
    if (!port || *end || p <= 0 || p > 65535)
        fail("HEXHIL_LINK_PORT is not set to a port (hexhil run starts the firmware)");
    sock = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_port = htons((uint16_t)p);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (sock < 0 || connect(sock, (struct sockaddr *)&addr, sizeof addr) != 0)
        fail("cannot connect to the simulator on 127.0.0.1");
    int one = 1;
    setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    uint8_t hello[64];
    uint16_t n = byte_and_text(hello, sizeof hello, HX_LINK_VERSION, runtime);
    size_t body = request(HX_OP_HELLO, hello, n);
    if (body < 2)
        fail("broken link: a hello reply without version and switches");
    if (reply[8] != HX_LINK_VERSION) {
        char text[120];
        snprintf(text, sizeof text, "link version mismatch: the host speaks version %u, "
                 "this firmware speaks %u", reply[8], HX_LINK_VERSION);
        fail(text);
    }
    switches = reply[9];
    memcpy(config, reply + 10, body - 2);
    config[body - 2] = 0;
}

int hx_link_is_open(void) { return sock >= 0; }
const char *hx_link_config(void) { return config; }
uint64_t hx_link_t_us(void) { return t_us; }
uint8_t hx_link_switches(void) { return switches; }

void hx_link_post(uint8_t op, const void *payload, uint16_t n) { queue(op, payload, n); }

void hx_link_event(uint8_t kind, const char *text)
{
    uint8_t buf[1024];
    queue(HX_OP_EVENT, buf, byte_and_text(buf, sizeof buf, kind, text));
}

void hx_link_can_send(uint16_t id, const uint8_t *data, uint8_t dlc)
{
    uint8_t buf[11];
    if (dlc > 8)
        dlc = 8;
    put_u16(buf, id);
    buf[2] = dlc;
    memcpy(buf + 3, data, dlc);
    queue(HX_OP_CAN, buf, (uint16_t)(3 + dlc));
}

void hx_link_baud(uint32_t bps)
{
    uint8_t buf[4];
    for (int i = 0; i < 4; i++)
        buf[i] = (bps >> (8 * i)) & 0xFF;
    queue(HX_OP_BAUD, buf, sizeof buf);
}

uint16_t hx_link_transact(const uint8_t *tx, uint16_t ntx, uint8_t *rx, uint16_t nrx,
                          uint32_t timeout_us)
{
    static uint8_t buf[6 + 65529];
    if (nrx > HX_MAX_RX_LEN)
        nrx = HX_MAX_RX_LEN;
    if (ntx > sizeof buf - 6)
        fail("a transact's tx bytes do not fit one message");
    put_u16(buf, nrx);
    for (int i = 0; i < 4; i++)
        buf[2 + i] = (timeout_us >> (8 * i)) & 0xFF;
    memcpy(buf + 6, tx, ntx);
    size_t got = request(HX_OP_TRANSACT, buf, (uint16_t)(6 + ntx));
    if (got > nrx)
        got = nrx;
    memcpy(rx, reply + 8, got);
    return (uint16_t)got;
}

static uint8_t take_frames(size_t body)
{
    if (body < 3)
        fail("broken link: a sleep reply without flags, switches and count");
    uint8_t flags = reply[8], n = reply[10];
    switches = reply[9];
    if (body < 3 + (size_t)n * 11)
        fail("broken link: a sleep reply shorter than its CAN records");
    for (unsigned i = 0; i < n; i++) {
        const uint8_t *r = reply + 11 + 11 * i;
        if (ring_count == CAN_RING)
            continue;   /* the firmware's CAN inbox is full: the frame is lost */
        unsigned k = (ring_head + ring_count++) % CAN_RING;
        ring[k].id = r[0] | (r[1] << 8);
        ring[k].dlc = r[2] > 8 ? 8 : r[2];
        memcpy(ring[k].data, r + 3, 8);
    }
    return flags;
}

uint8_t hx_link_sleep(uint64_t wake_us)
{
    uint8_t p[8];
    for (int i = 0; i < 8; i++)
        p[i] = (wake_us >> (8 * i)) & 0xFF;
    uint8_t flags = take_frames(request(HX_OP_SLEEP, p, 8));
    while (flags & HX_FLAG_MORE)
        flags = (flags & ~HX_FLAG_MORE) | take_frames(request(HX_OP_MORE, NULL, 0));
    return flags;
}

int hx_link_can_recv(uint16_t *id, uint8_t data[8], uint8_t *dlc)
{
    if (!ring_count)
        return 0;
    *id = ring[ring_head].id;
    *dlc = ring[ring_head].dlc;
    memcpy(data, ring[ring_head].data, 8);
    ring_head = (ring_head + 1) % CAN_RING;
    ring_count--;
    return 1;
}

void hx_link_close(void)
{
    if (sock < 0)
        return;
    if (out_len)
        flush();
    close(sock);
    sock = -1;
}
