/* A cycle's status reads: link version 2's R (docs/link.md "R reads"), with the SYNC_WRITE
 * the firmware sends before them in the same batch (its W). The R's rules live here and
 * nowhere else: its check, each read in order, tried again while its reply is not its
 * servo's status and retries are left, skipped when the read it names did not succeed,
 * each attempt packed into the reply, the bus time and wire time counted.
 *
 * An X (one transaction) is an R of one read without retries whose tx is the rest of the
 * payload (`one`), and a W with no R after it an R of no reads: their wire and bus time
 * are counted here too.
 *
 * An attempt is carried out here where the line is plain (the Python side says so in
 * `fast`: nothing on the line, no fault, no monitor, a world stepped by its own advance):
 * a clean READ to one servo of the bank that hx_serves, 8 bytes out, the servo's status
 * (hx_read) after its Return Delay, read back whole; the same integer times and bytes as
 * the line's general model (hil/servobus/line.py master_write, master_read). Every other attempt is
 * the line's (ATTEMPT), in Python, as is the master's reading of a reply it does not read
 * whole (HEAR), and a W this does not take whole (WRITE); the Python side (status_reads.py)
 * carries it out, puts what the master heard into the reply and whether it passed the
 * master's test, and calls again. The clock reaching the world's next physics step hands
 * back too (ADVANCE: the world steps; the bytes heard stay in the log, which the Python
 * side hands on, in order, at every other return, and then empties). A servo hx_sync_write
 * leaves to its own Python handle, or an ID or Baud Rate the W changed: WRITE_LEFT. */
#include "servo_core.h"

/* an attempt's phase; OUTSIDE: the Python side carried it out */
enum { START = 0, SERVO = 1, HEARD = 2, WRITTEN = 3, OUTSIDE = 4, WRITTEN_OUTSIDE = 5 };

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

static int malformed(struct reads *s, int why, int r, int skip, int announced)
{
    s->why = why;
    s->r = r;
    s->i = skip;
    s->at = announced;
    return HX_MALFORMED;
}

/* A read's tx length: its u8 ntx; an X's, the rest of the payload */
static int tx_len(const struct reads *s, const unsigned char *h)
{
    return s->one ? s->len - 1 - LINK_READ_LEN : h[11];
}

/* The R's reads fit its payload, each skips on an earlier one, and their replies, every
 * attempt at its most, fit a reply (an X's nrx the link server checks) */
static int check(struct reads *s)
{
    const unsigned char *p = s->payload;
    if (s->len < 1)
        return malformed(s, HX_WHY_LENGTH, 0, 0, 1);
    int n = p[0], at = 1, room = LINK_MAX_REPLY_LEN - 9;
    for (int r = 0; r < n; r++) {
        if (at + LINK_READ_LEN > s->len)
            return malformed(s, HX_WHY_LENGTH, r, 0, at + LINK_READ_LEN);
        const unsigned char *h = p + at;
        int retries = h[2], skip = h[4], nrx = h[5] | (h[6] << 8);
        if (skip != LINK_NO_SKIP && skip >= r)
            return malformed(s, HX_WHY_SKIP, r, skip, 0);
        room -= (1 + retries) * (LINK_ATTEMPT_HEAD_LEN + nrx);
        at += LINK_READ_LEN + tx_len(s, h);
    }
    if (at != s->len)
        return malformed(s, HX_WHY_LENGTH, n, 0, at);
    if (room < 0 && !s->one)
        return malformed(s, HX_WHY_ROOM, n, 0, 0);
    return HX_DONE;
}

/* A clean 8-byte READ with its checksum right */
static int clean_read(const unsigned char *tx, int ntx)
{
    int sum = tx[2] + tx[3] + tx[4] + tx[5] + tx[6];
    return ntx == 8 && tx[0] == 0xFF && tx[1] == 0xFF && tx[3] == 4 && tx[4] == DXL_READ
        && (~sum & 0xFF) == tx[7];
}

/* The W: one whole broadcast SYNC_WRITE with its checksum right, as Bus._deliver takes it
 * whole (anything else goes through the line's parser, in Python) */
static int write_whole(const struct reads *s)
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

/* An exchange's bus time (from t0_us to now) and wire time: what the master sent and heard
 * of others, not its own echo, at its byte time, rounded half to even */
static void count(struct reads *s, int64_t ntx, int64_t m)
{
    int64_t own = s->echo ? (ntx < m ? ntx : m) : 0;
    s->busy_us += s->t_us - s->t0_us;
    s->wire_us += (int64_t)rint((double)(ntx + m - own) * s->byte_us);
}

int hx_reads(struct reads *s)
{
    const unsigned char *p = s->payload;
    if (s->at == 0) {                 /* a new R, and the W before it */
        int bad = check(s);
        if (bad)
            return bad;
        s->log_len = s->nrec = 0;
        s->at = 1;
        s->r = s->k = s->phase = 0;
        s->tx_bytes = s->rx_bytes = s->packets = s->replies = s->busy_us = s->wire_us = 0;
        s->body[0] = 0;
        s->body_len = 1;
        if (s->write_len) {
            s->t0_us = s->t_us;
            if (!s->fast || !write_whole(s)) {
                s->phase = WRITTEN_OUTSIDE;
                return HX_WRITE;
            }
            heard(s, s->t_us, 'T', s->write, s->write_len);   /* Bus.master_write */
            s->tx_bytes += s->write_len;
            s->t_us += wire_us(s, s->write_len);
            s->phase = WRITTEN;
            if (s->t_us >= s->next_step_us)
                return HX_ADVANCE;
        }
    }
    if (s->phase == WRITTEN_OUTSIDE) {
        count(s, s->write_len, 0);
        s->phase = START;
    } else if (s->phase == WRITTEN) {  /* then to the servos */
        s->packets += 1;
        count(s, s->write_len, 0);
        s->phase = START;
        *s->changed = 0;
        s->i = hx_sync_write(s->bank, 0, s->t_us, s->write + 5, s->write_len - 6, s->changed);
        if (s->i < s->bank->n || *s->changed)
            return HX_WRITE_LEFT;
    }
    while (s->r < p[0]) {
        const unsigned char *h = p + s->at, *tx = h + LINK_READ_LEN;
        int dev_id = h[0], nparams = h[1], retries = h[2], flags = h[3], skip = h[4];
        int nrx = h[5] | (h[6] << 8), ntx = tx_len(s, h);
        int64_t timeout_us;
        uint32_t to;
        memcpy(&to, h + 7, 4);
        timeout_us = to;
        if (s->phase == START) {
            if (skip != LINK_NO_SKIP && s->done[skip] != 1) {
                s->done[s->r++] = -1;
                s->at += LINK_READ_LEN + ntx;
                continue;
            }
            s->t0_us = s->t_us;
            int i = s->fast && !(flags & LINK_READ_ECHO) && clean_read(tx, ntx)
                ? s->index[tx[2]] : -1;
            int64_t t1 = s->t_us + wire_us(s, 8);
            s->ntx = ntx;
            if (i < 0 || !hx_serves(s->bank, i, t1)) {
                s->phase = OUTSIDE;    /* the line's general model carries it out */
                return HX_ATTEMPT;
            }
            s->i = i;
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
                if (m > nrx || t_last > deadline) {
                    s->phase = OUTSIDE;   /* bytes left on the line, or cut off */
                    return HX_HEAR;
                }
                s->rx_bytes += m;
                heard(s, start, 'R', s->reply, m);
                t_end = m == nrx ? t_last : deadline;
            }
            s->t_us = t_end;
            s->phase = HEARD;
            /* protocol/dynamixel/v1.py status_ok: a servo's status is one whole packet (hx_read
             * builds it), so the master's test comes down to its ID and its length */
            s->ok = m == 6 + nparams && s->reply[2] == dev_id;
            memcpy(s->body + s->body_len + LINK_ATTEMPT_HEAD_LEN, s->reply, (size_t)m);
            if (t_end >= s->next_step_us)
                return HX_ADVANCE;
        }
        /* HEARD or OUTSIDE: the attempt's m bytes are in the body after their head; into
         * the reply, then the retry rule */
        int m = s->m;
        unsigned char *b = s->body + s->body_len;
        memcpy(b, &s->t_us, 8);
        b[8] = (unsigned char)(m & 0xFF);
        b[9] = (unsigned char)(m >> 8);
        s->body_len += LINK_ATTEMPT_HEAD_LEN + m;
        s->body[0] += 1;
        count(s, ntx, m);
        s->phase = START;
        if (s->ok || s->k >= retries) {
            s->done[s->r++] = (int8_t)(s->ok != 0);
            s->k = 0;
            s->at += LINK_READ_LEN + ntx;
        } else {
            s->k += 1;
        }
    }
    return HX_DONE;
}
