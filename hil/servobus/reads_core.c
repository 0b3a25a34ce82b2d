/* A cycle's status reads on a plain line: link version 2's R (hil/servobus/status_reads.py,
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

enum { START = 0, SERVO = 1, HEARD = 2, WRITTEN = 3 };   /* an attempt's phase */

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

/* status_reads.py parse's checks, and this path's own: every read a clean 8-byte READ, no echo */
static int checked(struct reads *s)
{
    const unsigned char *p = s->payload;
    if (s->len < 1)
        return 0;
    int n = p[0], at = 1, room = LINK_MAX_REPLY_LEN - 9;
    for (int r = 0; r < n; r++) {
        if (at + LINK_READ_LEN > s->len)
            return 0;
        const unsigned char *h = p + at;
        int retries = h[2], flags = h[3], skip = h[4], nrx = h[5] | (h[6] << 8), ntx = h[11];
        if ((skip != LINK_NO_SKIP && skip >= r) || flags || ntx != 8
            || at + LINK_READ_LEN + 8 > s->len)
            return 0;
        const unsigned char *tx = h + LINK_READ_LEN;
        int sum = tx[2] + tx[3] + tx[4] + tx[5] + tx[6];
        if (tx[0] != 0xFF || tx[1] != 0xFF || tx[3] != 4 || tx[4] != DXL_READ
            || (~sum & 0xFF) != tx[7])
            return 0;
        room -= (1 + retries) * (LINK_ATTEMPT_HEAD_LEN + nrx);
        at += LINK_READ_LEN + 8;
    }
    return at == s->len && room >= 0;
}

/* The W: one whole broadcast SYNC_WRITE with its checksum right, as Bus._deliver takes it
 * whole (anything else goes through the line's parser, in Python) */
static int write_checked(const struct reads *s)
{
    const unsigned char *w = s->write;
    int n = s->write_len, sum = 0;
    if (n < 6 || w[0] != 0xFF || w[1] != 0xFF || w[2] != DXL_BROADCAST_ID || w[3] + 4 != n
        || w[4] != DXL_SYNC_WRITE)
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
            return HX_FALLBACK;
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
                return HX_ADVANCE;
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
            return HX_WRITE_LEFT;
    }
    while (s->r < p[0]) {
        const unsigned char *h = p + s->at, *tx = h + LINK_READ_LEN;
        int dev_id = h[0], nparams = h[1], retries = h[2], skip = h[4];
        int nrx = h[5] | (h[6] << 8);
        int64_t timeout_us;
        uint32_t to;
        memcpy(&to, h + 7, 4);
        timeout_us = to;
        if (s->phase == START) {
            if (skip != LINK_NO_SKIP && s->done[skip] != 1) {
                s->done[s->r++] = -1;
                s->at += LINK_READ_LEN + 8;
                continue;
            }
            int i = s->index[tx[2]];
            int64_t t1 = s->t_us + wire_us(s, 8);
            if (i < 0 || !hx_serves(s->bank, i, t1))
                return HX_PYTHON;     /* no servo in the bank, or hx_read would leave it */
            s->i = i;
            s->t0_us = s->t_us;
            s->t1_us = t1;
            heard(s, s->t_us, 'T', tx, 8);
            s->tx_bytes += 8;
            s->packets += 1;
            s->t_us = t1;
            s->phase = SERVO;
            if (t1 >= s->next_step_us)
                return HX_ADVANCE;
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
                    : 2 * (int64_t)s->bank->table[i][AX12_RETURN_DELAY_TIME]
                      + s->bank->servo[i]->held_us;
                int64_t start = s->t1_us + delay, t_last = start + wire_us(s, m);
                s->replies += 1;
                s->start_us = start;
                s->m = m;
                if (m > nrx || t_last > deadline)
                    return HX_PYTHON_REPLY;   /* bytes left on the line, or cut off */
                s->rx_bytes += m;
                heard(s, start, 'R', s->reply, m);
                t_end = m == nrx ? t_last : deadline;
            }
            s->t_us = t_end;
            s->phase = HEARD;
            if (t_end >= s->next_step_us)
                return HX_ADVANCE;
        }
        /* HEARD: the attempt into the reply, then the retry rule */
        int m = s->m;
        unsigned char *b = s->body + s->body_len;
        memcpy(b, &s->t_us, 8);
        b[8] = (unsigned char)(m & 0xFF);
        b[9] = (unsigned char)(m >> 8);
        memcpy(b + LINK_ATTEMPT_HEAD_LEN, s->reply, (size_t)m);
        s->body_len += LINK_ATTEMPT_HEAD_LEN + m;
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
            s->at += LINK_READ_LEN + 8;
        } else {
            s->k += 1;
        }
    }
    return HX_DONE;
}
