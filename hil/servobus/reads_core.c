/* A cycle's status reads on a plain line: link version 2's R (hil/link/server.py _reads,
 * docs/link.md "R reads") carried out in one call, where the Python code makes about thirty
 * calls an attempt (Bus.transact, the master's status test, the reply's packing), with the
 * SYNC_WRITE the firmware sends before them in the same batch (its W: Bus.master_write of
 * one whole broadcast SYNC_WRITE, then the servo bank's hx_sync_write). Each
 * attempt is what Bus.transact does for a READ to one servo: 8 bytes out, the servo's
 * status (hx_read) after its Return Delay, read back whole; the same integer times, the
 * same reply bytes, the same retry and skip rules.
 *
 * The Python side (reads_core.py) hands over the payload and the line's clock, and gets
 * control back whenever something here cannot be done: the clock reaching the world's next
 * physics step (ADVANCE: the world steps; the bytes heard stay in the log, which the Python
 * side hands on, in order, where it takes over or the R is done, and then empties);
 * an attempt this does not serve (PYTHON: the general path takes over before it; after its
 * servo answered, with a reply the master does not read whole, PYTHON_REPLY); a payload
 * this does not check (FALLBACK, before doing anything: the general path carries the W and
 * the R out and raises what it finds wrong); a servo hx_sync_write leaves to its own Python
 * handle, or an ID or Baud Rate the W changed (WRITE_LEFT: the Python code finishes the
 * write, then the reads go on here, or from the first in the general path after the line
 * re-indexed). */
#include "servo_core.h"

enum { DONE = 0, ADVANCE = 1, PYTHON = 2, PYTHON_REPLY = 3, FALLBACK = 4, WRITE_LEFT = 5 };
enum { START = 0, SERVO = 1, HEARD = 2, WRITTEN = 3 };
enum { HEAD = 12, NO_SKIP = 0xFF, MAX_REPLY = 2048, ATTEMPT_HEAD = 10, US_BITS = 10000000,
       READ = 0x02, RETURN_DELAY = 5, BROADCAST = 0xFE, SYNC_WRITE = 0x83 };

struct reads {
    const struct bank *bank;
    const unsigned char *payload;
    int32_t len;
    const int16_t *index;         /* 256: the bank index of the one servo an ID reaches; -1 */
    int64_t baud;
    int64_t delay_override_us;    /* -1: each servo's own Return Delay Time */
    int64_t t_us;                 /* the line's clock */
    int64_t next_step_us;         /* the clock reaching this steps the world */
    int32_t r, k, at, phase;      /* read r, whose head is at payload[at]; its attempt k */
    int32_t i, m;                 /* the attempt's servo (bank index) and reply length */
    int64_t t0_us, t1_us, start_us;
    int8_t done[256];             /* per read: 1 it succeeded, 0 it failed, -1 skipped */
    unsigned char reply[64];
    unsigned char body[MAX_REPLY];   /* the reply after its time: u8 attempts, then each */
    int32_t body_len;
    unsigned char log[32768];     /* heard since the Python side last took it (serial_stream.py):
                                     u64 t, u8 'T'/'R', the bytes; at most ~200 attempts an R */
    int32_t log_len;
    unsigned char lens[1024];     /* each record's length */
    int32_t nrec;
    int64_t tx_bytes, rx_bytes, packets, replies, busy_us, wire_us;
    const unsigned char *write;   /* the W before the reads, or NULL (write_len 0) */
    int32_t write_len;
    int32_t *changed;             /* the bank's flag: the W changed an ID or Baud Rate */
};

static int64_t wire_us(const struct reads *s, int64_t n) { return n * US_BITS / s->baud; }

static void heard(struct reads *s, int64_t t_us, char dir, const unsigned char *d, int n)
{
    unsigned char *p = s->log + s->log_len;
    memcpy(p, &t_us, 8);
    p[8] = (unsigned char)dir;
    memcpy(p + 9, d, (size_t)n);
    s->log_len += 9 + n;
    s->lens[s->nrec++] = (unsigned char)n;
}

/* server.py _reads's checks, and this path's own: every read a clean 8-byte READ, no echo */
static int checked(struct reads *s)
{
    const unsigned char *p = s->payload;
    if (s->len < 1)
        return 0;
    int n = p[0], at = 1, room = MAX_REPLY - 9;
    for (int r = 0; r < n; r++) {
        if (at + HEAD > s->len)
            return 0;
        const unsigned char *h = p + at;
        int retries = h[2], flags = h[3], skip = h[4], nrx = h[5] | (h[6] << 8), ntx = h[11];
        if ((skip != NO_SKIP && skip >= r) || flags || ntx != 8 || at + HEAD + 8 > s->len)
            return 0;
        const unsigned char *tx = h + HEAD;
        int sum = tx[2] + tx[3] + tx[4] + tx[5] + tx[6];
        if (tx[0] != 0xFF || tx[1] != 0xFF || tx[3] != 4 || tx[4] != READ
            || (~sum & 0xFF) != tx[7])
            return 0;
        room -= (1 + retries) * (ATTEMPT_HEAD + nrx);
        at += HEAD + 8;
    }
    return at == s->len && room >= 0;
}

/* The W: one whole broadcast SYNC_WRITE with its checksum right, as Bus._deliver takes it
 * whole (anything else goes through the line's parser, in Python) */
static int write_checked(const struct reads *s)
{
    const unsigned char *w = s->write;
    int n = s->write_len, sum = 0;
    if (n < 6 || w[0] != 0xFF || w[1] != 0xFF || w[2] != BROADCAST || w[3] + 4 != n
        || w[4] != SYNC_WRITE)
        return 0;
    for (int j = 2; j < n - 1; j++)
        sum += w[j];
    return (~sum & 0xFF) == w[n - 1];
}

static int64_t wire_time_us(const struct reads *s, int64_t n)
{   /* server.py's round(n * byte_us): half to even, as rint */
    return (int64_t)rint((double)n * ((double)US_BITS / (double)s->baud));
}

int hx_reads(struct reads *s)
{
    const unsigned char *p = s->payload;
    if (s->at == 0) {                 /* a new R, and the W before it */
        if (!checked(s) || (s->write_len && !write_checked(s)))
            return FALLBACK;
        s->log_len = s->nrec = 0;
        s->at = 1;
        s->r = s->k = s->phase = 0;
        s->tx_bytes = s->rx_bytes = s->packets = s->replies = s->busy_us = s->wire_us = 0;
        s->body[0] = 0;
        s->body_len = 1;
        if (s->write_len) {           /* Bus.master_write: on the wire, then to the servos */
            s->t0_us = s->t_us;
            heard(s, s->t_us, 'T', s->write, s->write_len);
            s->tx_bytes += s->write_len;
            s->t_us += wire_us(s, s->write_len);
            s->phase = WRITTEN;
            if (s->t_us >= s->next_step_us)
                return ADVANCE;
        }
    }
    if (s->phase == WRITTEN) {
        s->packets += 1;
        s->busy_us += s->t_us - s->t0_us;
        s->wire_us += wire_time_us(s, s->write_len);
        s->phase = START;
        *s->changed = 0;
        s->i = hx_sync_write(s->bank, 0, s->t_us, s->write + 5, s->write_len - 6, s->changed);
        if (s->i < s->bank->n || *s->changed)
            return WRITE_LEFT;
    }
    while (s->r < p[0]) {
        const unsigned char *h = p + s->at, *tx = h + HEAD;
        int dev_id = h[0], nparams = h[1], retries = h[2], skip = h[4];
        int nrx = h[5] | (h[6] << 8);
        int64_t timeout_us;
        uint32_t to;
        memcpy(&to, h + 7, 4);
        timeout_us = to;
        if (s->phase == START) {
            if (skip != NO_SKIP && s->done[skip] != 1) {
                s->done[s->r++] = -1;
                s->at += HEAD + 8;
                continue;
            }
            int i = s->index[tx[2]];
            int64_t t1 = s->t_us + wire_us(s, 8);
            if (i < 0 || !hx_serves(s->bank, i, t1))
                return PYTHON;        /* no servo in the bank, or hx_read would leave it */
            s->i = i;
            s->t0_us = s->t_us;
            s->t1_us = t1;
            heard(s, s->t_us, 'T', tx, 8);
            s->tx_bytes += 8;
            s->packets += 1;
            s->t_us = t1;
            s->phase = SERVO;
            if (t1 >= s->next_step_us)
                return ADVANCE;
        }
        if (s->phase == SERVO) {
            int i = s->i;
            int m = hx_read(s->bank, i, s->t1_us, tx[5], tx[6], s->reply);
            int64_t deadline = s->t1_us + timeout_us, t_end = deadline;
            s->m = 0;
            if (m > 0) {
                /* the margin's override, else TableServo.return_delay_us: register 5 in
                 * 2 us units (ax12.return_delay_us), plus how long the READ waited */
                int64_t delay = s->delay_override_us >= 0 ? s->delay_override_us
                    : 2 * (int64_t)s->bank->table[i][RETURN_DELAY] + s->bank->servo[i]->held_us;
                int64_t start = s->t1_us + delay, t_last = start + wire_us(s, m);
                s->replies += 1;
                s->start_us = start;
                s->m = m;
                if (m > nrx || t_last > deadline)
                    return PYTHON_REPLY;   /* bytes left on the line, or cut off */
                s->rx_bytes += m;
                heard(s, start, 'R', s->reply, m);
                t_end = m == nrx ? t_last : deadline;
            }
            s->t_us = t_end;
            s->phase = HEARD;
            if (t_end >= s->next_step_us)
                return ADVANCE;
        }
        /* HEARD: the attempt into the reply, then the retry rule */
        int m = s->m;
        unsigned char *b = s->body + s->body_len;
        memcpy(b, &s->t_us, 8);
        b[8] = (unsigned char)(m & 0xFF);
        b[9] = (unsigned char)(m >> 8);
        memcpy(b + ATTEMPT_HEAD, s->reply, (size_t)m);
        s->body_len += ATTEMPT_HEAD + m;
        s->body[0] += 1;
        s->busy_us += s->t_us - s->t0_us;
        s->wire_us += wire_time_us(s, 8 + m);
        s->phase = START;
        /* protocol/dynamixel/v1.py status_ok: a servo's status is one whole packet (hx_read
         * builds it), so the master's test comes down to its ID and its length */
        int ok = m == 6 + nparams && s->reply[2] == dev_id;
        if (ok || s->k >= retries) {
            s->done[s->r++] = (int8_t)ok;
            s->k = 0;
            s->at += HEAD + 8;
        } else {
            s->k += 1;
        }
    }
    return DONE;
}
