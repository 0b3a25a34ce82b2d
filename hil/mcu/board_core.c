/* The ELF board's hot path compiled (hil/mcu/board_core.py loads it with ctypes): the event
 * heap, USART1, USART2 and USART6 at register level with their byte timing (usart.py), the
 * servo line's outgoing burst, PA1's turns and PB's switch reads, SysTick's wraps and CSR
 * reads, the exception model's entry, return and choice, the run loop, quiet waits and the
 * poll skipper's known waits.
 *
 * It fronts the peripherals' MMIO region for Unicorn: the USARTs' pages, 32-bit stores to
 * GPIOA's ODR and BSRR and reads of GPIOB's IDR are served here, every other access goes
 * to the Python callbacks (hil/mcu/mmio.py) through a function pointer.
 * Python is called only where the board's Python state is needed: a Python timer falling
 * due, a USART's interrupt line high, USART2's transmitter going idle (the servo line's
 * burst is sent), a console byte, a DMA request, a poll loop seen for the first time, a
 * USART's bus clock once a clock change. It also runs the board's loop (``bc_loop``) while
 * no Python takes part, and makes every exception entry and return, whose failures core.py
 * names. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define NONE (-1LL)
enum { REG_R0, REG_R1, REG_R2, REG_R3, REG_R12, REG_LR, REG_XPSR, REG_CONTROL, REG_MSP,
       REG_PSP, REG_S0, REG_FPSCR, REG_IPSR, REG_PC, REG_FAULTMASK, REG_PRIMASK, REG_BASEPRI,
       REG_COUNT };

typedef int64_t (*py_call_t)(int kind, int64_t a, int64_t b);
typedef int (*py_timer_t)(int tid, int64_t at_fs);
typedef uint64_t (*mmio_read_t)(void *uc, uint64_t offset, unsigned size, void *ud);
typedef void (*mmio_write_t)(void *uc, uint64_t offset, unsigned size, uint64_t value, void *ud);
typedef int (*reg_batch_t)(void *uc, int *ids, void *const *vals, int count);
typedef int (*emu_start_t)(void *uc, uint64_t begin, uint64_t until, uint64_t timeout,
                           size_t count);
typedef int (*mem_read_t)(void *uc, uint64_t address, void *bytes, size_t size);
typedef int (*emu_stop_t)(void *uc);

typedef struct { int64_t at; uint64_t seq; int32_t tid; uint32_t gen; } entry_t;

/* bc_t, shared with Python (hil/mcu/board_core.py ``Shared``), set3_t and cover_t: their
 * fields and the constants the two sides share are hil/mcu/board_layout.py's, which setup.py
 * writes as board_layout.h; the library keeps its fingerprint, checked at load */
#include "board_layout.h"
typedef struct set3 set3_t;
typedef struct bc bc_t;
typedef struct cover cover_t;
typedef struct usart usart_t;
_Static_assert(REG_COUNT == N_REGID, "board_layout.py N_REGID: the REG_* registers");
_Static_assert(N_EXC <= ACTIVE_MAX, "board_layout.py ACTIVE_MAX: every exception active at once");
const char hx_layout[] = HX_LAYOUT;

/* quiet loops (quiet.py): the state recorded at the end of a quiet chunk (cycle,
   registers, SRAM), the misses' back-off, Unicorn's ids of the registers read */
typedef struct quiet {
    int64_t cyc, backoff;
    int32_t nregs, _pad;
    int32_t *ids;
    uint64_t *regs, *now;
    void **ptrs;
    uint8_t *sram;
} quiet_t;


static int64_t floordiv(__int128 a, __int128 b) {
    __int128 q = a / b;
    if ((a % b != 0) && ((a < 0) != (b < 0))) q -= 1;
    return (int64_t)q;
}

/* --- time -------------------------------------------------------------------------- */
static int64_t now_cyc(bc_t *s) { return s->running ? s->chunk0 + (int64_t)*s->ctr - 1 : s->cyc; }

static int64_t fs_at(bc_t *s, int64_t cyc) {
    if (s->fs_per_cyc) return s->fs0 + (cyc - s->cyc0) * s->fs_per_cyc;
    return s->fs0 + floordiv((__int128)(cyc - s->cyc0) * FS_PER_S, s->hz);
}

static int64_t cycle_of(bc_t *s, int64_t fs) {
    if (s->fs_per_cyc) return s->cyc0 - floordiv(s->fs0 - fs, s->fs_per_cyc);
    return s->cyc0 - floordiv(-(__int128)(fs - s->fs0) * s->hz, FS_PER_S);
}

int64_t bc_now_fs(bc_t *s) { return fs_at(s, now_cyc(s)); }

/* --- the event heap (board_core.py ``Events``: ties in the order set) ------------------ */
static int before(entry_t *a, entry_t *b) {
    return a->at < b->at || (a->at == b->at && a->seq < b->seq);
}

static void heap_pop(bc_t *s) {
    entry_t *h = s->heap;
    h[0] = h[--s->n];
    int i = 0;
    for (;;) {
        int l = 2 * i + 1, r = l + 1, m = i;
        if (l < s->n && before(&h[l], &h[m])) m = l;
        if (r < s->n && before(&h[r], &h[m])) m = r;
        if (m == i) break;
        entry_t t = h[i]; h[i] = h[m]; h[m] = t;
        i = m;
    }
}

/* drop cancelled entries off the top; the earliest live time */
static void settle(bc_t *s) {
    while (s->n && s->gen[s->heap[0].tid] != s->heap[0].gen) heap_pop(s);
    s->next_at = s->n ? s->heap[0].at : NONE;
}

int bc_timer_new(bc_t *s) {
    if (s->ntimers % 64 == 0) {
        s->gen = realloc(s->gen, (s->ntimers + 64) * sizeof *s->gen);
        s->tat = realloc(s->tat, (s->ntimers + 64) * sizeof *s->tat);
    }
    s->gen[s->ntimers] = 0;
    s->tat[s->ntimers] = NONE;
    return s->ntimers++;
}

void bc_timer_set(bc_t *s, int tid, int64_t at) {
    if (s->n == s->cap) {
        s->cap = s->cap ? 2 * s->cap : 256;
        s->heap = realloc(s->heap, s->cap * sizeof *s->heap);
    }
    entry_t e = {at, ++s->seq, tid, ++s->gen[tid]};
    s->tat[tid] = at;
    int i = s->n++;
    entry_t *h = s->heap;
    while (i > 0 && before(&e, &h[(i - 1) / 2])) {
        h[i] = h[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h[i] = e;
    settle(s);
}

void bc_timer_clear(bc_t *s, int tid) {
    s->gen[tid]++;
    s->tat[tid] = NONE;
    settle(s);
}

int64_t bc_timer_at(bc_t *s, int tid) { return s->tat[tid]; }

static void usart_shifted(bc_t *s, int i, int64_t at);
static void usart_idle(bc_t *s, int i);

static void pend(bc_t *s, int exc) {
    uint32_t bit = 1u << (exc & 31);
    if (!(s->pend[exc >> 5] & bit)) {
        s->pend[exc >> 5] |= bit;
        s->pending_n++;
    }
}

/* SysTick's wrap (system.py SysTick ``_wrapped``): COUNTFLAG, the exception pended with
 * TICKINT, the next wrap a reload later at HCLK or HCLK/8 */
static void systick_wrapped(bc_t *s, int64_t at) {
    s->st_countflag = 1;
    if (s->st_csr & SYST_TICKINT) pend(s, EXC_SYSTICK);
    if (s->st_rvr == 0) return;
    int64_t hz = (s->st_csr & SYST_CLKSOURCE) ? s->hz : s->hz / 8;
    __int128 span = (__int128)(s->st_rvr + 1) * FS_PER_S;
    bc_timer_set(s, s->st_tid, at + (int64_t)((span + hz - 1) / hz));
}

/* SysTick's CSR read (systick.py ``read``): ENABLE, TICKINT, CLKSOURCE and COUNTFLAG,
 * which the read clears */
static uint32_t systick_csr(bc_t *s) {
    uint32_t v = ((uint32_t)s->st_csr & SYST_CONTROL) | (s->st_countflag ? SYST_COUNTFLAG : 0);
    s->st_countflag = 0;
    return v;
}

static void rx_deliver(bc_t *s, int64_t at);

/* whose timer ``tid`` is: USART i's byte end (i), its IDLE (-2 - i), neither (-1) */
static int usart_timer(bc_t *s, int tid) {
    for (int i = 0; i < N_USART; i++) {
        usart_t *u = &s->usart[i];
        if (!u->made) continue;
        if (tid == u->tid) return i;
        if (tid == u->idle_tid) return -2 - i;
    }
    return -1;
}

/* Fire every timer due by ``now_fs`` in time order: 1 when any fired, -1 on a Python error */
int bc_fire_due(bc_t *s, int64_t now_fs) {
    int fired = 0;
    settle(s);
    while (s->n && s->heap[0].at <= now_fs && !s->err) {
        entry_t e = s->heap[0];
        heap_pop(s);
        s->gen[e.tid]++;
        s->tat[e.tid] = NONE;
        int i = usart_timer(s, e.tid);
        if (i >= 0) {
            usart_shifted(s, i, e.at);
        } else if (i < -1) {
            usart_idle(s, -2 - i);
        } else if (e.tid == s->st_tid) {
            systick_wrapped(s, e.at);
        } else if (e.tid == s->rx_tid) {
            rx_deliver(s, e.at);
        } else if (s->touched++, s->py_timer(e.tid, e.at)) {
            s->err = 1;
        }
        fired = 1;
        settle(s);
    }
    return s->err ? -1 : fired;
}

/* The run loop's head (board.py ``run``): the timers due at the chunk's start fired, then
   the next chunk's length, to the next event (1 to ``max_chunk`` instructions); -1 when a
   Python timer raised */
static int64_t head(bc_t *s, int64_t max_chunk) {
    if (bc_fire_due(s, fs_at(s, s->cyc)) < 0) return -1;
    if (s->next_at < 0) return max_chunk;
    int64_t n = cycle_of(s, s->next_at) - s->cyc;
    return n < 1 ? 1 : n > max_chunk ? max_chunk : n;
}

/* --- USART1, USART2 and USART6 (usart.py) ---------------------------------------------
 * ``i`` is the USART's place in ``s->usart``: SERVO_USART's bytes go to the servo line's
 * burst, the consoles' to Python's console, a byte at a time. */
static const int STOP_HALF_BITS[4] = {STOP_HALF_BITS_0, STOP_HALF_BITS_1, STOP_HALF_BITS_2,
                                      STOP_HALF_BITS_3};

static int64_t py(bc_t *s, int kind, int64_t a, int64_t b) {
    if (s->err) return -1;
    s->touched++;
    int64_t r = s->py_call(kind, a, b);
    if (r == PY_RAISED) s->err = 1;
    return r;
}

int64_t bc_divider(bc_t *s, int i) {
    usart_t *u = &s->usart[i];
    int64_t brr = u->brr & 0xFFFF;
    if (u->cr1 & OVER8) return (brr >> 4) * 8 + (brr & 7);
    return brr;
}

/* a frame's length; kept until CR1, CR2, BRR or the bus clock change */
static int64_t frame_fs(bc_t *s, int i) {
    usart_t *u = &s->usart[i];
    if (!u->frame_fs) {
        int64_t half = 2 + 2 * ((u->cr1 & M_9BIT) ? 9 : 8)
                       + STOP_HALF_BITS[(u->cr2 >> STOP_SHIFT) & 3];
        int64_t div = bc_divider(s, i);
        if (!u->pclk) u->pclk = py(s, PY_PCLK, i, 0);
        int64_t pclk = u->pclk;
        if (pclk <= 0) {
            u->pclk = 0;
            return 1;
        }
        u->frame_fs = floordiv((__int128)half * FS_PER_S * (div > 1 ? div : 1), 2 * pclk);
    }
    return u->frame_fs;
}

static void line(bc_t *s, int i, int level) {
    usart_t *u = &s->usart[i];
    if (level) {
        u->line = 1;
        py(s, PY_LINE, 1, i);
    } else if (u->line) {
        u->line = 0;
        py(s, PY_LINE, 0, i);
    }
}

static void irq(bc_t *s, int i) {
    usart_t *u = &s->usart[i];
    int sr = u->sr, cr1 = u->cr1;
    if (!(cr1 & (TXEIE | TCIE | RXNEIE | IDLEIE)) && !(u->cr3 & EIE)) {
        line(s, i, 0);
        return;
    }
    int level = (cr1 & UE) && (((cr1 & TXEIE) && (sr & TXE)) || ((cr1 & TCIE) && (sr & TC))
                               || ((cr1 & RXNEIE) && (sr & (RXNE | ORE)))
                               || ((cr1 & IDLEIE) && (sr & IDLE))
                               || ((u->cr3 & EIE) && (sr & ORE)));
    line(s, i, level);
}

/* a byte started leaving the shift register at ``start_fs``, gone at ``end_fs`` */
static void sent(bc_t *s, int i, int byte, int64_t start_fs, int64_t end_fs) {
    if (i != SERVO_USART) {
        py(s, PY_SENT, byte, end_fs);
        return;
    }
    if (!s->burst_n) {
        s->burst_fs = start_fs;
        s->burst_dir = s->direction;
    }
    if (s->burst_n == s->burst_cap) {
        s->burst_cap = s->burst_cap ? 2 * s->burst_cap : 1024;
        s->burst = realloc(s->burst, s->burst_cap);
    }
    s->burst[s->burst_n++] = (uint8_t)byte;
}

static void transmit(bc_t *s, int i, int byte, int64_t at) {
    usart_t *u = &s->usart[i];
    int64_t end = at + frame_fs(s, i);
    bc_timer_set(s, u->tid, end);
    u->sr &= ~TC;
    sent(s, i, byte, at, end);
    if ((u->cr3 & HDSEL) && (u->cr1 & RE)) u->echo = byte;
}

void bc_usart_received(bc_t *s, int i, int byte);
void bc_usart_dma_request(bc_t *s, int i);

static void usart_shifted(bc_t *s, int i, int64_t at) {
    usart_t *u = &s->usart[i];
    int echo = u->echo;
    if (echo >= 0) {
        u->echo = -1;
        bc_usart_received(s, i, echo);
    }
    if (u->tdr >= 0) {
        int byte = u->tdr;
        u->tdr = -1;
        u->sr |= TXE;
        transmit(s, i, byte, at);
        if (u->cr3 & DMAT) bc_usart_dma_request(s, i);
    } else {
        u->sr |= TC;
        if (i == SERVO_USART) py(s, PY_IDLE, at, 0);   /* the burst goes to the link */
    }
    irq(s, i);
}

static void write_dr(bc_t *s, int i, int byte) {
    usart_t *u = &s->usart[i];
    if (!((u->cr1 & UE) && (u->cr1 & TE))) return;
    if (s->tat[u->tid] == NONE) {
        transmit(s, i, byte, bc_now_fs(s));
    } else {
        u->tdr = byte;
        u->sr &= ~TXE;
    }
}

/* TXE with DMAT: the DMA fills DR (twice when the shift register is free too) */
void bc_usart_dma_request(bc_t *s, int i) {
    usart_t *u = &s->usart[i];
    while ((u->cr3 & DMAT) && u->dma_tx && (u->sr & TXE) && (u->cr1 & UE) && (u->cr1 & TE)) {
        int64_t byte = py(s, PY_DMA_TX, i, 0);
        if (byte < 0) return;
        write_dr(s, i, (int)byte);
    }
}

/* a byte arrived at the RX pin now */
void bc_usart_received(bc_t *s, int i, int byte) {
    usart_t *u = &s->usart[i];
    if (!((u->cr1 & UE) && (u->cr1 & RE))) return;
    if (u->sr & RXNE) {
        u->sr |= ORE;
    } else {
        u->rdr = byte;
        u->sr |= RXNE;
        if ((u->cr3 & DMAR) && u->dma_rx && py(s, PY_DMA_RX, byte, i) > 0) u->sr &= ~RXNE;
    }
    u->idle_at = bc_now_fs(s) + frame_fs(s, i);
    if (u->cr1 & IDLEIE) bc_timer_set(s, u->idle_tid, u->idle_at);
    irq(s, i);
}

/* the line idle a frame since the last byte received: IDLE */
static void usart_idle(bc_t *s, int i) {
    usart_t *u = &s->usart[i];
    u->idle_at = 0;
    bc_timer_clear(s, u->idle_tid);
    u->sr |= IDLE;
    irq(s, i);
}

/* IDLE as of now (read without IDLEIE, nothing was scheduled for it) */
static void idle_now(bc_t *s, int i) {
    usart_t *u = &s->usart[i];
    if (u->idle_at && bc_now_fs(s) >= u->idle_at) usart_idle(s, i);
}

uint32_t bc_usart_read(bc_t *s, int i, int off) {
    usart_t *u = &s->usart[i];
    switch (off) {
    case DR:
        u->sr &= ~(RXNE | ORE | (u->idle_seen ? IDLE : 0));
        u->idle_seen = 0;
        irq(s, i);
        return (uint32_t)u->rdr;
    case SR:
        idle_now(s, i);
        u->idle_seen = (u->sr & IDLE) != 0;
        return (uint32_t)u->sr;
    case BRR: return (uint32_t)u->brr;
    case CR1: return (uint32_t)u->cr1;
    case CR2: return (uint32_t)u->cr2;
    case CR3: return (uint32_t)u->cr3;
    case GTPR: return (uint32_t)u->gtpr;
    default: return 0;
    }
}

void bc_usart_write(bc_t *s, int i, int off, uint32_t value) {
    usart_t *u = &s->usart[i];
    if (off == DR) {
        write_dr(s, i, value & 0x1FF);
    } else if (off == SR) {
        u->sr &= (int32_t)(value | ~(uint32_t)(TC | RXNE | LBD | CTS));
    } else if (off >= BRR && off <= GTPR) {
        int32_t v = value & 0xFFFF;
        switch (off) {
        case BRR: u->brr = v; break;
        case CR1: u->cr1 = v; break;
        case CR2: u->cr2 = v; break;
        case CR3: u->cr3 = v; break;
        default: u->gtpr = v;
        }
        if (off == CR1 || off == CR2 || off == BRR) u->frame_fs = 0;
        if (off == CR1 && !(value & UE)) {
            u->sr = TXE | TC;
            u->tdr = -1;
            bc_timer_clear(s, u->tid);
            u->idle_at = u->idle_seen = 0;
        }
        if (off == CR1) {
            bc_timer_clear(s, u->idle_tid);
            if ((value & IDLEIE) && u->idle_at) {
                idle_now(s, i);
                if (u->idle_at) bc_timer_set(s, u->idle_tid, u->idle_at);
            }
        }
        if (off == CR3) bc_usart_dma_request(s, i);
    }
    irq(s, i);
}

/* the USART at its reset state (power-on, a system reset); its timers made once a board */
void bc_usart_reset(bc_t *s, int i) {
    usart_t *u = &s->usart[i];
    if (!u->made) {
        u->tid = bc_timer_new(s);
        u->idle_tid = bc_timer_new(s);
        u->made = 1;
    }
    u->sr = TXE | TC;
    u->brr = u->cr1 = u->cr2 = u->cr3 = u->gtpr = 0;
    u->tdr = u->echo = -1;
    u->rdr = 0;
    u->frame_fs = u->pclk = 0;
    u->line = u->dma_tx = u->dma_rx = 0;
    bc_timer_clear(s, u->tid);
    u->idle_at = u->idle_seen = 0;
    bc_timer_clear(s, u->idle_tid);
}

/* --- the poll skipper's known waits (poll.py) ---------------------------------------- */
int bc_next_exception(bc_t *s);

/* core.py ``stop``: the chunk ends at the instruction running now (a read: it runs again) */
static void stop(bc_t *s) {
    if (s->running && !s->stopped) {
        s->stopped = 1;
        s->emu_stop(s->uc);
    }
}

/* core.py ``cut_after``: the chunk ends after the instruction running now (a write that
   made an exception ready), Unicorn's count lowered to it */
static void cut_after(bc_t *s) {
    if (s->running) {
        s->ctr[1] = s->ctr[0];
        s->cut = 1;
    }
}

static unsigned slot_of(uint32_t a, uint32_t b, uint32_t c) {
    return (a * 2654435761u ^ b * 40503u ^ c * 97u) % WAITS;
}

static int set_add(set3_t *t, uint32_t a, uint32_t b, uint32_t c) {
    unsigned i = slot_of(a, b, c);
    for (int k = 0; k < WAITS; k++, i = (i + 1) % WAITS) {
        uint32_t *w = t->slot[i];
        if (w[0] == a && w[1] == b && w[2] == c) return 0;
        if (w[0] == 0) {
            w[0] = a; w[1] = b; w[2] = c;
            t->n++;
            return 0;
        }
    }
    return -1;
}

static int set_has(set3_t *t, uint32_t a, uint32_t b, uint32_t c) {
    unsigned i = slot_of(a, b, c);
    for (int k = 0; k < WAITS; k++, i = (i + 1) % WAITS) {
        uint32_t *w = t->slot[i];
        if (w[0] == 0) return 0;
        if (w[0] == a && w[1] == b && w[2] == c) return 1;
    }
    return 0;
}

/* poll.py ``_known_wait``: 0 added (or already there), -1 full (the loop is then skipped
   at its second read, by the watch's verdict) */
int bc_add_wait(bc_t *s, uint32_t pc, uint32_t addr, uint32_t value) {
    return set_add(&s->waits, pc, addr, value);
}

/* poll.py ``_loops_ok`` False: a read at ``pc`` waits on nothing (``cycles`` is 0) */
int bc_add_not_loop(bc_t *s, uint32_t pc, uint32_t addr, uint32_t cycles) {
    return set_add(&s->nots, pc, addr, cycles);
}

/* A known poll loop skipped at its read: time jumps to the next event, which fires now; an
   exception it makes ready stops the chunk (the read runs again). Whether time moved. */
int bc_jump_here(bc_t *s) {
    int64_t now = now_cyc(s);
    settle(s);
    if (s->next_at == NONE) return 0;
    int64_t cyc = cycle_of(s, s->next_at);
    if (cyc <= now) return 0;
    if (s->running) s->chunk0 += cyc - now;
    else s->cyc += cyc - now;
    s->skipped += cyc - now;
    s->poll_valid = 0;
    bc_fire_due(s, bc_now_fs(s));
    if (s->pending_n && bc_next_exception(s) >= 0) {   /* ready: the read runs again */
        s->reread = 1;
        stop(s);
    }
    return 1;
}

/* A side-effect-free read of a pollable register (any peripheral's): the poll detector's
   view. A new read is noted, and skipped when it is a known wait's; the same read again at
   a site known to wait on nothing is noted too; anything else is the watch's, in Python
   (poll.py ``repeated``). 1 when the wait was skipped here: the read is to be done again. */
int bc_polled(bc_t *s, uint32_t addr, uint32_t value) {
    if (s->reread) {
        s->reread = 0;
        return 0;
    }
    if (!s->poll_valid || (uint32_t)s->poll_addr != addr || (uint32_t)s->poll_value != value) {
        s->poll_valid = 1;
        s->poll_addr = (int32_t)addr;
        s->poll_value = (int32_t)value;
        s->poll_at = now_cyc(s);
        if (!s->watching && set_has(&s->waits, *s->pc, addr, value)) return bc_jump_here(s);
        return 0;
    }
    int64_t now = now_cyc(s), cycles = now - s->poll_at;
    if (!s->watching && s->nots.n >= 0 && cycles >= 0 && cycles < 0x80000000LL &&
        set_has(&s->nots, *s->pc, addr, 0)) {
        s->poll_at = now;         /* the same read again, known to wait on nothing */
        return 0;
    }
    return py(s, PY_POLLED, addr, value) > 0;
}

int bc_masked_ready(bc_t *s);

/* --- Unicorn's MMIO callbacks for the peripheral region -------------------------------- */
static void due(bc_t *s) {
    if (s->next_at != NONE && s->next_at <= bc_now_fs(s)) bc_fire_due(s, bc_now_fs(s));
}

static void failed(bc_t *s) {
    if (s->err) {
        s->py_call(PY_FAILED, 0, 0);
        s->err = 0;
    }
}

static uint32_t sized(uint32_t word, uint64_t offset, unsigned size) {
    if (size == 4 && !(offset & 3)) return word;
    return (uint32_t)((word >> (8 * (offset & 3))) & ((1ULL << (8 * size)) - 1));
}

/* --- GPIOA and GPIOB (gpio.py, board.py, servo_line.py) ------------------------------
 * PA1's turns and PB's IDR, the two accesses a servo-driving firmware makes every cycle.
 * A turn is done here when nothing but the link's direction message follows it in Python
 * (servo_line.py ``direction_turned``): no burst unsent, no reply bytes waiting on a turn
 * to transmit. */

/* A port's IDR: outputs read ODR, analog pins 0, inputs and alternate functions 0 where
   grounded, else their pull-up (PUPDR 01) */
uint32_t bc_idr(uint32_t moder, uint32_t pupdr, uint32_t odr, uint32_t grounded) {
    uint32_t out = 0, analog = 0, pull = 0;
    for (int pin = 0; pin < 16; pin++) {
        uint32_t mode = (moder >> 2 * pin) & 3;
        out |= (uint32_t)(mode == 1) << pin;
        analog |= (uint32_t)(mode == 3) << pin;
        pull |= (uint32_t)(((pupdr >> 2 * pin) & 3) == 1) << pin;
    }
    return (odr & out) | (pull & ~(out | analog | grounded));
}

/* ODR after a store of ``value`` to ODR or BSRR (its upper half resets pins, its lower half
   sets them: set wins) */
uint32_t bc_odr_after(uint32_t old, int off, uint32_t value) {
    if (off == GPIO_BSRR) return (old & ~(value >> 16)) | (value & 0xFFFF);
    return value & 0xFFFF;
}

static uint32_t port_idr(bc_t *s, int port) {
    uint32_t grounded = port == 1 ? (uint32_t)s->switches & SWITCH_MASK : 0;
    return bc_idr(s->gpio_moder[port], s->gpio_pupdr[port], s->gpio_odr[port], grounded);
}

/* gpio.py ``read`` of PB's IDR with board.py ``fresh_switches`` before it */
static uint32_t switches_idr(bc_t *s) {
    if (bc_now_fs(s) / FS_PER_US - s->last_request_us >= TICK_US) py(s, PY_SWITCHES, 0, 0);
    return port_idr(s, 1);
}

static uint64_t read_switches(bc_t *s, uint64_t offset, unsigned size) {
    due(s);
    uint32_t value = sized(switches_idr(s), offset, size);
    if (!s->err && bc_polled(s, (uint32_t)(PERIPH_BASE + offset), value))
        value = sized(switches_idr(s), offset, size);
    failed(s);
    return value;
}

/* A 32-bit store to GPIOA's ODR or BSRR; 0 when Python is to do it */
static int write_porta(bc_t *s, int off, uint32_t value) {
    due(s);
    s->poll_valid = 0;
    if (s->err) {                 /* a timer raised: the chunk ends with it, the store undone */
        failed(s);
        return 1;
    }
    uint32_t old = s->gpio_odr[0];
    uint32_t odr = bc_odr_after(old, off, value);
    int level = ((s->gpio_moder[0] >> 2 * DIRECTION_PIN) & 3) == 1
        ? (int)(odr >> DIRECTION_PIN & 1) : 0;
    if (level != s->direction) {
        if (s->burst_n || (level && s->rx_n > s->rx_head) || s->turns_n >= TURNS)
            return 0;
        s->turn_us[s->turns_n] = bc_now_fs(s) / FS_PER_US;
        s->turn_level[s->turns_n++] = level;
        s->direction = level;
    }
    s->gpio_odr[0] = odr;
    if (s->pending_n && (bc_next_exception(s) >= 0 || bc_masked_ready(s))) cut_after(s);
    failed(s);
    return 1;
}

/* the USART whose page ``offset`` is in, with its clock on; -1 where none */
static int usart_page(bc_t *s, uint64_t offset) {
    static const int pages[N_USART] = {USART_PAGE_0, USART_PAGE_1, USART_PAGE_2};
    for (int i = 0; i < N_USART; i++)
        if ((int)(offset >> 10) == pages[i]) return s->usart[i].live ? i : -1;
    return -1;
}

uint64_t bc_mmio_read(void *uc, uint64_t offset, unsigned size, void *ud) {
    bc_t *s = ud;
    s->mmio_n++;
    if ((offset >> 10) == GPIOA_PAGE + 1 && (offset & 0x3FC) == GPIO_IDR && s->gpio_live & 2)
        return read_switches(s, offset, size);
    int i = usart_page(s, offset);
    if (i < 0) {
        s->touched++;
        return s->py_read(uc, offset, size, 0);
    }
    due(s);
    int off = (int)(offset & 0x3FC);
    uint32_t value = sized(bc_usart_read(s, i, off), offset, size);
    if (off == DR || off == GTPR || off > GTPR) {
        s->poll_valid = 0;
    } else if (bc_polled(s, (uint32_t)(PERIPH_BASE + offset), value)) {
        value = sized(bc_usart_read(s, i, off), offset, size);
    }
    failed(s);
    return value;
}

void bc_mmio_write(void *uc, uint64_t offset, unsigned size, uint64_t value, void *ud) {
    bc_t *s = ud;
    s->mmio_n++;
    if ((offset >> 10) == GPIOA_PAGE && size == 4 && s->gpio_live & 1 &&
        ((offset & 0x3FF) == GPIO_ODR || (offset & 0x3FF) == GPIO_BSRR) &&
        write_porta(s, (int)(offset & 0x3FF), (uint32_t)value))
        return;
    int i = usart_page(s, offset);
    if (i < 0) {
        s->touched++;
        s->py_write(uc, offset, size, value, 0);
        return;
    }
    due(s);
    s->poll_valid = 0;
    int off = (int)(offset & 0x3FC);
    if (size < 4) {
        int shift = 8 * (int)(offset & 3);
        uint64_t mask = ((1ULL << (8 * size)) - 1) << shift;
        if (off == SR || off == BRR || off == CR1 || off == CR2 || off == CR3)
            value = (bc_usart_read(s, i, off) & ~mask) | ((value << shift) & mask);
        else
            value = value << shift;
    }
    bc_usart_write(s, i, off, (uint32_t)(value & 0xFFFFFFFF));
    if (s->pending_n && (bc_next_exception(s) >= 0 || bc_masked_ready(s))) cut_after(s);
    failed(s);
}

/* Unicorn's MMIO read callback for the private peripheral bus: SysTick's CSR, which an
 * interpreter's SysTick handler and its microsecond clock read each time, is answered here
 * (the chunk still ends in Python, as after mmio.py's ``ppb_read``); every other register
 * is Python's. */
uint64_t bc_ppb_read(void *uc, uint64_t offset, unsigned size, void *ud) {
    bc_t *s = ud;
    if ((offset & ~3ULL) != SYSTICK_BASE - PPB_BASE || s->st_tid < 0)
        return s->py_ppb_read(uc, offset, size, 0);
    s->touched++;
    s->mmio_n++;
    due(s);
    uint32_t value = sized(systick_csr(s), offset, size);
    if (bc_polled(s, (uint32_t)(PPB_BASE + offset), value))
        value = sized(systick_csr(s), offset, size);
    failed(s);
    return value;
}

/* the PC as Unicorn's registers say it (bc_count's word holds the last instruction's own
   address) */
static uint32_t reg_pc(bc_t *s) {
    int rid = s->regid[REG_PC];
    uint64_t pc = 0;
    void *ptr = &pc;
    s->reg_read_batch(s->uc, &rid, &ptr, 1);
    return (uint32_t)pc;
}

/* --- the exception model: entry and return (core.py ``enter``, ``leave``) --------------- */

/* ``n`` words at ``addr``: from SRAM's buffer, else through Unicorn; 0 when read */
static int read_words(bc_t *s, uint32_t addr, uint32_t *v, uint32_t n) {
    if (addr >= SRAM_BASE && addr <= SRAM_BASE + SRAM_SIZE - 4 * n) {
        memcpy(v, s->sram + (addr - SRAM_BASE), 4 * n);      /* little-endian, as the core */
        return 0;
    }
    return s->mem_read(s->uc, addr, v, 4 * n);
}

/* The return from the innermost exception through ``exc_return``: the exception popped, its
 * frame unstacked (8 words, or 26 with the FPU's S0-S15 and FPSCR as EXC_RETURN says), the
 * registers written in one batch, ``pc_next`` the return address. Its number, or a LEAVE_*
 * code: in thread mode, or to thread mode with exceptions still active (a lockup: the
 * exception is popped, as the chip leaves it), or nothing changed (the frame or the
 * registers could not be read). */
int bc_unstack(bc_t *s, uint32_t exc_return) {
    if (s->nactive < 1) return LEAVE_THREAD;
    int to_thread = (exc_return & 0xF) == (RETURN_THREAD_MSP & 0xF) ||
                    (exc_return & 0xF) == (RETURN_THREAD_PSP & 0xF);
    if (to_thread && s->nactive > 1) {
        s->nactive--;
        return LEAVE_LOCKUP;
    }
    int *id = s->regid;
    int rid[3] = {id[REG_CONTROL], id[REG_MSP], id[REG_PSP]};
    uint64_t st[3] = {0, 0, 0};
    void *sp3[3] = {&st[0], &st[1], &st[2]};
    if (s->reg_read_batch(s->uc, rid, sp3, 3)) return LEAVE_UNREAD;
    uint32_t control = (uint32_t)st[0], msp = (uint32_t)st[1], psp_value = (uint32_t)st[2];
    int psp = (exc_return & 0xF) == (RETURN_THREAD_PSP & 0xF);
    uint32_t sp = psp ? psp_value : msp;
    int fpu = !(exc_return & RETURN_NO_FP);
    control = (control & ~CONTROL_FPCA) | (fpu ? CONTROL_FPCA : 0);   /* as EXC_RETURN says */
    uint32_t n = fpu ? 26 : 8;
    uint32_t v[26];
    if (read_words(s, sp, v, n)) return LEAVE_UNREAD;
    uint32_t xpsr = v[7];
    sp = sp + 4 * n + ((xpsr & XPSR_ALIGNED) ? 4 : 0);
    int exc = s->active[--s->nactive];
    uint32_t ipsr = s->nactive ? (uint32_t)s->active[s->nactive - 1] : 0;
    /* the frame's registers, the state, the FP context, IPSR, the stack pointer, the PC */
    int ids[40];
    uint64_t vals[40];
    void *ptrs[40];
    int k = 0;
    static const int frame[6] = {REG_R0, REG_R1, REG_R2, REG_R3, REG_R12, REG_LR};
    for (int i = 0; i < 6; i++) { ids[k] = id[frame[i]]; vals[k++] = v[i]; }
    ids[k] = id[REG_XPSR]; vals[k++] = xpsr & ~0x3FFu;
    ids[k] = id[REG_CONTROL]; vals[k++] = control;
    ids[k] = id[REG_MSP]; vals[k++] = msp;
    ids[k] = id[REG_PSP]; vals[k++] = psp_value;
    if (fpu) {
        for (int i = 0; i < 16; i++) { ids[k] = id[REG_S0] + i; vals[k++] = v[8 + i]; }
        ids[k] = id[REG_FPSCR]; vals[k++] = v[24];
    }
    ids[k] = id[REG_IPSR]; vals[k++] = ipsr;
    if (psp) {
        ids[k] = id[REG_CONTROL]; vals[k++] = control | CONTROL_SPSEL;
        ids[k] = id[REG_PSP];
    }
    else ids[k] = id[REG_MSP];
    vals[k++] = sp;
    ids[k] = id[REG_PC]; vals[k++] = v[6] | 1;
    for (int i = 0; i < k; i++) ptrs[i] = &vals[i];
    s->reg_write_batch(s->uc, ids, ptrs, k);
    s->pc_next = v[6] & ~1u;
    return exc;
}

/* The return done here, in Unicorn's interrupt hook, when nothing follows it in Python: no
 * exception pending (no tail-chaining), a system exception or an IRQ whose line is low (a
 * line held high pends it again), not asleep, no sleep-on-exit, no lockup or fault to name.
 * Everything else goes to board.py's ``intr``. */
static int leave(bc_t *s) {
    if (!s->pc || !s->uc || s->nactive < 1 || s->pending_n || s->sleeping) return 0;
    /* Unicorn's registers hold the EXC_RETURN branched to (bc_count's word the branch's) */
    uint32_t exc_return = reg_pc(s) | 1;
    int exc = s->active[s->nactive - 1];
    int to_thread = (exc_return & 0xF) == (RETURN_THREAD_MSP & 0xF) ||
                    (exc_return & 0xF) == (RETURN_THREAD_PSP & 0xF);
    if ((exc >= 16 && s->lines[(exc - 16) >> 5] >> ((exc - 16) & 31) & 1) ||
        (to_thread && s->nactive > 1) || (s->nactive == 1 && s->sleep_on_exit))
        return 0;
    if (bc_unstack(s, exc_return) < 0) return 0;   /* nothing changed: Python names it */
    s->fast_returns++;
    return 1;
}

/* Take exception ``exc`` at ``pc``: the frame stacked (the FP context's too where one is
 * active), the handler's vector fetched from the table at ``vtor_base``, the registers
 * written, the exception active. The vector, or an ENTER_* code: ``fault_at`` holds the
 * frame's address (a stack overflow, a frame off SRAM) or the vector (none there). */
int64_t bc_enter(bc_t *s, int exc, uint32_t pc, int fpu, uint32_t vtor_base) {
    int *id = s->regid;
    int ids[40];
    uint64_t r[40];
    void *ptrs[40];
    int k = 0;
    static const int state[10] = {REG_R0, REG_R1, REG_R2, REG_R3, REG_R12, REG_LR, REG_XPSR,
                                  REG_CONTROL, REG_MSP, REG_PSP};
    for (int i = 0; i < 10; i++) ids[k++] = id[state[i]];
    if (fpu) {
        for (int i = 0; i < 16; i++) ids[k++] = id[REG_S0] + i;
        ids[k++] = id[REG_FPSCR];
    }
    for (int i = 0; i < k; i++) { r[i] = 0; ptrs[i] = &r[i]; }
    if (s->reg_read_batch(s->uc, ids, ptrs, k)) return ENTER_UNREAD;
    uint32_t xpsr = (uint32_t)r[6], control = (uint32_t)r[7];
    int psp = !s->nactive && (control & CONTROL_SPSEL);
    fpu = fpu && (control & CONTROL_FPCA);   /* an FP context is active: the extended frame */
    int64_t sp = psp ? (uint32_t)r[9] : (uint32_t)r[8];
    uint32_t v[26];
    int n = 0;
    for (int i = 0; i < 6; i++) v[n++] = (uint32_t)r[i];
    v[n++] = pc & ~1u;
    v[n++] = xpsr | XPSR_THUMB;
    if (fpu) {
        for (int i = 10; i < 27; i++) v[n++] = (uint32_t)r[i];
        v[n++] = 0;
    }
    if (sp & 4) { sp -= 4; v[7] |= XPSR_ALIGNED; }
    sp -= 4 * n;
    s->fault_at = sp;
    if (sp < SRAM_BASE) return ENTER_BELOW_SRAM;
    if (sp > SRAM_BASE + SRAM_SIZE - 4 * n) return ENTER_OFF_SRAM;
    memcpy(s->sram + (sp - SRAM_BASE), v, 4 * n);
    uint64_t at = (uint64_t)vtor_base + 4 * (uint64_t)exc;
    uint32_t vector;
    s->fault_at = (int64_t)at;
    if (at >= FLASH_BASE && at <= FLASH_BASE + FLASH_SIZE - 4)
        memcpy(&vector, s->flash + (at - FLASH_BASE), 4);
    else if (at > 0xFFFFFFFCu || read_words(s, (uint32_t)at, &vector, 1))
        return ENTER_NO_TABLE;
    s->fault_at = vector;
    if (vector == 0 || !(vector & 1)) return ENTER_NO_HANDLER;
    uint32_t exc_return = s->nactive ? RETURN_HANDLER
                                     : (psp ? RETURN_THREAD_PSP : RETURN_THREAD_MSP);
    if (fpu) exc_return &= ~(uint32_t)RETURN_NO_FP;
    k = 0;
    control &= ~CONTROL_FPCA;               /* the handler starts with no FP context */
    if (psp) {
        ids[k] = id[REG_PSP]; r[k++] = (uint64_t)sp;
        ids[k] = id[REG_CONTROL]; r[k++] = control & ~(uint32_t)CONTROL_SPSEL;
    } else {
        ids[k] = id[REG_MSP]; r[k++] = (uint64_t)sp;
        ids[k] = id[REG_CONTROL]; r[k++] = control;
    }
    ids[k] = id[REG_IPSR]; r[k++] = (uint32_t)exc;
    ids[k] = id[REG_LR]; r[k++] = exc_return;
    if (s->running) { ids[k] = id[REG_PC]; r[k++] = vector | 1; }
    for (int i = 0; i < k; i++) ptrs[i] = &r[i];
    s->reg_write_batch(s->uc, ids, ptrs, k);
    s->active[s->nactive++] = exc;
    s->sleeping = 0;
    return vector;
}

/* --- the NVIC's choice (system.py ``Nvic``) ----------------------------------------- */
static int priority(bc_t *s, int exc) { return exc <= 3 ? exc - 4 : s->prio[exc] & PRIORITY_BITS; }

static int group(bc_t *s, int prio) {
    return prio < 0 ? prio : prio & ~((2 << s->prigroup) - 1) & 0xFF;
}

/* exception ``exc``'s preemption priority (lower preempts; reset -3, NMI -2, HardFault -1) */
int bc_group_priority(bc_t *s, int exc) { return group(s, priority(s, exc)); }

/* the execution priority (lower preempts): the active exceptions' group priorities and
   PRIMASK, BASEPRI, FAULTMASK (-1: FAULTMASK; 256: nothing raises it) */
int bc_execution_priority(bc_t *s) {
    int level = 256;
    for (int i = 0; i < s->nactive; i++) {
        int g = group(s, priority(s, s->active[i]));
        if (g < level) level = g;
    }
    int ids[3] = {s->regid[REG_FAULTMASK], s->regid[REG_PRIMASK], s->regid[REG_BASEPRI]};
    uint64_t m[3] = {0, 0, 0};
    void *ptrs[3] = {&m[0], &m[1], &m[2]};
    s->reg_read_batch(s->uc, ids, ptrs, 3);
    if (m[0] & 1) return -1;
    if ((m[1] & 1) && level > 0) level = 0;
    int basepri = (int)(m[2] & PRIORITY_BITS);
    if (basepri && group(s, basepri) < level) level = group(s, basepri);
    return level;
}

/* the lowest exception from ``from`` on that is pending and enabled (a system exception
   always is), -1 when none: the pending bits walked a word at a time */
int bc_pending_from(bc_t *s, int from) {
    for (int w = from >> 5; w < (N_EXC + 31) >> 5; w++) {
        uint32_t bits = s->pend[w] & (w == from >> 5 ? ~0u << (from & 31) : ~0u);
        for (; bits; bits &= bits - 1) {
            int e = 32 * w + __builtin_ctz(bits);
            if (e >= N_EXC) return -1;
            if (e < 16 || s->ena[(e - 16) >> 5] >> ((e - 16) & 31) & 1) return e;
        }
    }
    return -1;
}

/* a pending exception would preempt the active ones but for PRIMASK, BASEPRI or
   FAULTMASK */
int bc_masked_ready(bc_t *s) {
    int best = -1, best_p = 0;
    for (int e = bc_pending_from(s, 0); e >= 0; e = bc_pending_from(s, e + 1)) {
        int p = priority(s, e);
        if (best < 0 || p < best_p) { best = e; best_p = p; }
    }
    if (best < 0) return 0;
    int level = 256;
    for (int i = 0; i < s->nactive; i++) {
        int g = group(s, priority(s, s->active[i]));
        if (g < level) level = g;
    }
    return group(s, best_p) < level;
}

/* the pending exception that preempts what runs now, -1 when none */
int bc_next_exception(bc_t *s) {
    if (!s->pending_n) return -1;
    int best = -1, best_p = 0;
    for (int e = bc_pending_from(s, 0); e >= 0; e = bc_pending_from(s, e + 1)) {
        int p = priority(s, e);
        if (best < 0 || p < best_p) { best = e; best_p = p; }
    }
    if (best < 0) return -1;
    return group(s, best_p) < bc_execution_priority(s) ? best : -1;
}

/* The run loop's exception (board.py ``run``): the pending exception that preempts what
   runs now, taken at ``pc`` (no longer pending, its frame stacked): its number above bit 32
   and its vector below; -1 when none is ready; -2 - exc where its entry failed (only its
   pending bit cleared: Python names the fault) */
static int64_t take_next(bc_t *s, uint32_t pc, int fpu, uint32_t vtor_base) {
    int exc = bc_next_exception(s);
    if (exc < 0) return -1;
    uint32_t bit = 1u << (exc & 31);
    if (s->pend[exc >> 5] & bit) {
        s->pend[exc >> 5] &= ~bit;
        s->pending_n--;
    }
    int64_t vector = bc_enter(s, exc, pc, fpu, vtor_base);
    return vector < 0 ? -2 - exc : (int64_t)exc << 32 | vector;
}

/* The public engine's UC_HOOK_CODE (engine.py): before each instruction, its PC where the
   core reads it and one more in the count; past the chunk's length the chunk ends here, as
   emu_start's own count ends it */
void bc_count(void *uc, uint64_t address, uint32_t size, void *ud) {
    bc_t *s = ud;
    s->pub_pc = (uint32_t)address;
    if (++s->pub_count > s->pub_limit) s->emu_stop(uc);
}

/* Unicorn's interrupt hook (UC_HOOK_INTR) */
void bc_intr(void *uc, uint32_t intno, void *ud) {
    bc_t *s = ud;
    if (intno == INTR_EXC_EXIT && leave(s)) return;
    py(s, PY_INTR, intno, 0);
    failed(s);
}

/* --- the servo line's reply bytes (servo_line.py ``rx_arrives``/``deliver``) ------------- */
/* the burst just fetched: each byte with its arrival time */
void bc_rx_queue(bc_t *s, const int64_t *at, const uint8_t *bytes, int n) {
    if (n > s->rx_cap) {
        s->rx_cap = n;
        s->rx_at = realloc(s->rx_at, n * sizeof *s->rx_at);
        s->rx_byte = realloc(s->rx_byte, n);
    }
    memcpy(s->rx_at, at, n * sizeof *at);
    memcpy(s->rx_byte, bytes, n);
    s->rx_n = n;
    s->rx_head = 0;
}

/* the bytes arrived by ``at`` to USART2, the deliver timer at the next one */
static void rx_deliver(bc_t *s, int64_t at) {
    while (s->rx_head < s->rx_n && s->rx_at[s->rx_head] <= at && !s->err)
        bc_usart_received(s, SERVO_USART, s->rx_byte[s->rx_head++]);
    if (s->rx_head < s->rx_n && !s->err) bc_timer_set(s, s->rx_tid, s->rx_at[s->rx_head]);
}

int bc_rx_deliver(bc_t *s, int64_t at) {
    rx_deliver(s, at);
    return s->err ? -1 : 0;
}

/* --- the run loop (board.py ``run`` and core.py ``run``) ------------------------------ */
#define QUIET_LOUD 8             /* chunks with register accesses that end a quiet wait */

static int read16(bc_t *s, uint32_t addr, uint16_t *op) {
    if (addr >= FLASH_BASE && addr <= FLASH_BASE + FLASH_SIZE - 2) {
        memcpy(op, s->flash + (addr - FLASH_BASE), 2);
        return 0;
    }
    return s->mem_read(s->uc, addr, op, 2);
}

/* WFI ends: an enabled exception is pending, whatever its priority */
int bc_wakes(bc_t *s) {
    return s->pending_n && bc_pending_from(s, 0) >= 0;
}

/* A chunk: up to ``n`` instructions from ``pc_next`` (a WFI or WFE that ends it counts and
   puts the core to sleep); how many ran, or -1 when the chunk ended in something Python
   names (a callback's exception, a jump to 0, an error of Unicorn's: the LOOP_* code in
   ``loop_exc``, core.py ``chunk_fault``) */
int64_t bc_run_chunk(bc_t *s, int64_t n) {
    s->chunk0 = s->cyc;
    s->chunk_mmio = s->mmio_n;
    s->stopped = s->cut = 0;
    s->quiet_hold = 0;
    s->running = 1;
    s->hook_failed = 0;
    s->pub_count = 0;
    s->pub_limit = (uint64_t)n;
    int err = s->emu_start(s->uc, (uint32_t)s->pc_next | 1, 0, 0, 0);
    s->running = 0;
    if (s->hook_failed) {         /* raised as Unicorn's wrapper would: nothing updated */
        s->loop_exc = LOOP_HOOK_FAILED;
        return -1;
    }
    int64_t ran = (int64_t)*s->ctr - 1;
    s->pc_next = reg_pc(s);
    if (!err && ran < n && !s->stopped && !s->cut) {
        if (s->pc_next == 0) {
            s->loop_exc = LOOP_NULL_JUMP;
            return -1;
        }
        uint16_t op = 0;
        if (!read16(s, (uint32_t)s->pc_next - 2, &op) && (op == WFI || op == WFE)) {
            ran++;
            s->sleeping = 1;
        }
    }
    ran = ran < 0 ? 0 : ran > n ? n : ran;
    s->cyc = s->chunk0 + ran;     /* chunk0 has moved by any jump inside the chunk */
    s->executed += ran;
    if (err) {
        s->uc_err = err;
        s->loop_exc = LOOP_UC_ERROR;
        return -1;
    }
    return ran;
}

/* --- quiet loops (quiet.py) ------------------------------------------------------------ */

/* quiet.py's registers, by Unicorn's ids; 0 when the buffers cannot be had */
static void quiet_free(quiet_t *q) {
    if (!q) return;
    free(q->ids);
    free(q->regs);
    free(q->now);
    free(q->ptrs);
    free(q->sram);
    free(q);
}

int bc_quiet_init(bc_t *s, const int32_t *ids, int n) {
    quiet_t *q = calloc(1, sizeof *q);
    if (!q) return 0;
    q->ids = malloc(n * sizeof *q->ids);
    q->regs = calloc(n, sizeof *q->regs);
    q->now = calloc(n, sizeof *q->now);
    q->ptrs = malloc(n * sizeof *q->ptrs);
    q->sram = malloc(SRAM_SIZE);
    if (!q->ids || !q->regs || !q->now || !q->ptrs || !q->sram) {
        quiet_free(q);
        return 0;
    }
    memcpy(q->ids, ids, n * sizeof *ids);
    for (int i = 0; i < n; i++) q->ptrs[i] = &q->now[i];
    q->nregs = n;
    q->backoff = 1;
    quiet_free(s->q);
    s->q = q;
    s->q_seen = 0;
    return 1;
}

static void quiet_read(bc_t *s) {
    quiet_t *q = s->q;
    memset(q->now, 0, q->nregs * sizeof *q->now);
    s->reg_read_batch(s->uc, q->ids, q->ptrs, q->nregs);
}

/* a word at a time, 4 words a step: the toolchain's memcmp goes byte by byte */
static int same_words(const uint8_t *a, const uint8_t *b, size_t n) {
    for (size_t i = 0; i + 32 <= n; i += 32) {
        uint64_t x[4], y[4];
        memcpy(x, a + i, 32);
        memcpy(y, b + i, 32);
        if ((x[0] ^ y[0]) | (x[1] ^ y[1]) | (x[2] ^ y[2]) | (x[3] ^ y[3])) return 0;
    }
    return 1;
}

static int quiet_same(bc_t *s) {
    quiet_t *q = s->q;
    return !memcmp(q->now, q->regs, q->nregs * sizeof *q->now) &&
           same_words(s->sram, q->sram, SRAM_SIZE);
}

/* between chunks: time jumps to the next event; whether it moved */
int bc_skip_to_event(bc_t *s) {
    if (s->next_at < 0) return 0;
    int64_t cyc = cycle_of(s, s->next_at);
    if (cyc <= s->cyc) return 0;
    s->skipped += cyc - s->cyc;
    s->cyc = cyc;
    return 1;
}

/* A chunk of ``ran`` instructions made no register access and did not sleep: its end state
   recorded, or compared with the one a pass before (a miss backs off; the same state to the
   bit is a fixed point: time jumps to the next event and the state is held) */
static void quiet_chunk(bc_t *s, int64_t ran) {
    quiet_t *q = s->q;
    quiet_read(s);
    if (!s->q_seen || ran != QUIET_PASS || s->cyc - q->cyc != QUIET_PASS) {
        memcpy(q->regs, q->now, q->nregs * sizeof *q->now);
        memcpy(q->sram, s->sram, SRAM_SIZE);
        q->cyc = s->cyc;
        s->q_seen = 1;
        s->quiet_n = QUIET_PASS;
        return;
    }
    s->q_seen = 0;
    if (!quiet_same(s)) {         /* a miss */
        s->quiet_n = 0;
        s->quiet_wait = q->backoff;
        q->backoff = 2 * q->backoff < MAX_BACKOFF ? 2 * q->backoff : MAX_BACKOFF;
        return;
    }
    q->backoff = 1;
    if (bc_skip_to_event(s)) s->quiet_hold = 1;     /* the recorded state is the fixed point */
}

/* Nothing has run since the last skip: the state still the held one, time jumps again (1);
   else the hold ends */
static int quiet_held(bc_t *s) {
    quiet_read(s);
    if (quiet_same(s) && bc_skip_to_event(s)) return 1;
    s->quiet_hold = 0;
    return 0;
}

/* The board's loop (board.py ``run``) for as long as no Python takes part: the head, the
   exception taken, the sleep, the chunk, the lockup's first test. It returns where Python
   goes on (LOOP_*): after the head (a Python timer fired; ``loop_n`` is the chunk's
   length), after a chunk that called Python, or with what only Python does. ``n`` >= 0
   goes on with an iteration whose head Python saw. Under a debugger (``debug``) it returns
   before each chunk (LOOP_BEFORE_CHUNK, ``loop_n`` its length) and after it; ``n`` =
   LOOP_RESUME then runs the chunk of ``debug_n`` instructions the debugger allows. */
int bc_loop(bc_t *s, int64_t max_chunk, int64_t n) {
    int64_t ran;
    for (;;) {
        int64_t seen = s->touched;
        if (n == LOOP_RESUME) {
            n = s->debug_n;
            goto run;
        }
        if (n < 0) {
            n = head(s, max_chunk);
            if (n < 0) return LOOP_RAISED;
            if (s->touched != seen) {
                s->loop_n = n;
                return LOOP_AFTER_HEAD;
            }
        }
        if (s->quiet_n > 0 && n > s->quiet_n) n = s->quiet_n;
        s->loop_n = n;
        int64_t taken = take_next(s, (uint32_t)s->pc_next, s->fpu_on,
                                     s->vtor ? (uint32_t)s->vtor : FLASH_BASE);
        if (taken >= 0) {
            s->pc_next = taken & 0xFFFFFFFE;
        } else if (taken < -1) {
            s->loop_exc = (int32_t)(-2 - taken);
            return LOOP_ENTER;
        } else if (s->sleeping) {
            if (bc_wakes(s)) {
                s->sleeping = 0;
            } else {
                if (s->next_at < 0) return LOOP_NO_EVENT;
                int64_t wake = cycle_of(s, s->next_at);
                if (wake > s->cyc) s->cyc = wake;
                n = -1;
                continue;
            }
        }
        if (s->quiet_hold) {      /* still the confirmed fixed point? */
            if (taken == -1 && !s->sleeping && !(s->pending_n && bc_masked_ready(s))) {
                s->masked_steps = 0;
                if (quiet_held(s)) {
                    n = -1;
                    continue;
                }
            }
            s->quiet_hold = 0;
        }
        if (s->pending_n && bc_masked_ready(s)) {   /* taken right after its unmasking */
            if (s->masked_steps < MASKED_STEPS) {
                n = 1;
                s->masked_steps++;
            }
        } else {
            s->masked_steps = 0;
        }
        s->loop_n = n;
        if (s->debug) return LOOP_BEFORE_CHUNK;
    run:
        ran = bc_run_chunk(s, n);
        if (ran < 0) return s->loop_exc;
        if (s->touched != seen || s->watching || s->debug) return LOOP_AFTER_CHUNK;
        uint16_t op = 0;           /* a lockup's first test: Python's, as it reads */
        if (s->nactive && (read16(s, (uint32_t)s->pc_next, &op) || op == BRANCH_TO_SELF))
            return LOOP_AFTER_CHUNK;
        if (s->mmio_n != s->chunk_mmio) {
            if (++s->quiet_loud > QUIET_LOUD) s->quiet_n = 0;   /* no wait goes on */
        } else if (ran == n && !s->sleeping && !s->stopped && !s->cut) {
            s->quiet_loud = 0;
            if (s->quiet_wait > 0) s->quiet_wait--;       /* a quiet chunk: a look */
            else quiet_chunk(s, ran);
        }
        n = -1;
    }
}

/* what the heap, the burst and the timers took (the board's end) */
void bc_free(bc_t *s) {
    free(s->heap);
    free(s->gen);
    free(s->tat);
    free(s->burst);
    free(s->rx_at);
    free(s->rx_byte);
    quiet_free(s->q);
    s->q = NULL;
    s->q_seen = 0;
    s->rx_at = NULL;
    s->rx_byte = NULL;
    s->rx_n = s->rx_head = s->rx_cap = 0;
    s->heap = NULL;
    s->gen = NULL;
    s->tat = NULL;
    s->burst = NULL;
    s->n = s->cap = s->ntimers = s->burst_n = s->burst_cap = 0;
}

/* --coverage (hil/mcu/coverage.py ``LineCounter``): Unicorn's block hook, counting each
   block run by (address, size) in an open-addressed table the Python side allocated, so a
   covered run pays no Python call per block. A table three quarters full takes no new
   block (``lost`` counts them; the table is sized from the firmware's code to leave room). */

void bc_cover_block(void *uc, uint64_t address, uint32_t size, void *user) {
    (void)uc;
    cover_t *c = user;
    uint64_t key = (address << 32 | size) + 1;          /* 0: an empty slot */
    uint64_t i = (key * 0x9E3779B97F4A7C15ull) >> 29 & c->mask;
    while (c->keys[i] && c->keys[i] != key)
        i = (i + 1) & c->mask;
    if (!c->keys[i]) {
        if (4 * (c->used + 1) > 3 * (c->mask + 1)) {
            c->lost++;
            return;
        }
        c->keys[i] = key;
        c->used++;
    }
    c->counts[i]++;
}
