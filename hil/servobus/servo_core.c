/* The emulated AX-12's rules, their one implementation: the set-point its control table
 * gives its drive, a write's check and its effects, the health's step and the alarms, the
 * Present registers (ax12_servo.py's Servo calls each through servo_rules.py); and, built on
 * them, the two instructions of every cycle for a whole line in one call: a SYNC_WRITE
 * carried out by every servo, and a READ answered with its status packet, for servos whose
 * joints are a compiled drive bank (hil/world/drive_core.c, through the bank's state and
 * command). The IEEE operations of Python's arithmetic in its order, so the tables, the
 * drives and the trace are the same bits whichever path serves a servo (built with
 * -ffp-contract=off: no fused multiply-add; exp and rint are the C library's, which
 * CPython's math.exp and round call too). The servos' state lives in ctypes structures the
 * Python code reads and writes as attributes. Built by setup.py, which writes
 * servo_layout.h (the structs and the protocol's constants) from
 * hil/servobus/servo_layout.py. */
#include "servo_core.h"

const char hx_layout[] = HX_LAYOUT;   /* checked at load (hil/native.py) */

/* Python's min(a, b) and max(a, b): the first unless the second is strictly beyond it */
static double py_min(double a, double b) { return b < a ? b : a; }
static double py_max(double a, double b) { return b > a ? b : a; }
/* Python's int(round(x)) for the finite values below: half to even */
static int64_t py_round(double x) { return (int64_t)rint(x); }

static int u16(const unsigned char *t, int a) { return t[a] | (t[a + 1] << 8); }
static int wheel(const unsigned char *t)   /* both angle limits 0 */
{
    return !(u16(t, AX12_CW_ANGLE_LIMIT) || u16(t, AX12_CCW_ANGLE_LIMIT));
}

/* drive.py drive(): table t's set-point at supply_frac of 12 V into out: [0] the goal
 * (NaN: hold where it reads; +-inf: turn endlessly), [1] the speed limit, [2] the torque
 * limit's fraction, [3] Torque Enable, [4..9) the compliance registers (CW, CCW margin; CW,
 * CCW slope; punch). Joint mode stops the horn at the angle limits; a DC motor's no-load
 * speed and stall torque scale with its supply. position_rad, speed_rad_s: Goal Position's
 * and Moving Speed's values in SI units (servo_rules.py). */
void hx_setpoint(const double *position_rad, const double *speed_rad_s, const unsigned char *t,
                 double supply_frac, double *out)
{
    int speed = u16(t, AX12_MOVING_SPEED);
    double goal_rad, speed_limit;
    if (wheel(t)) {
        int mag = speed & 0x3FF;
        goal_rad = mag ? ((speed & AX12_DIRECTION_BIT) ? -INFINITY : INFINITY) : NAN;
        speed_limit = (double)mag * AX12_SPEED_UNIT * 2.0 * M_PI / 60.0;
    } else {
        int cw = u16(t, AX12_CW_ANGLE_LIMIT), ccw = u16(t, AX12_CCW_ANGLE_LIMIT),
            goal = u16(t, AX12_GOAL_POSITION);
        goal_rad = position_rad[goal < cw ? cw : (goal > ccw ? ccw : goal)];
        speed_limit = speed_rad_s[speed];
    }
    const unsigned char *m = t + AX12_CW_COMPLIANCE_MARGIN;
    out[0] = goal_rad;
    out[1] = py_min(speed_limit, AX12_NO_LOAD_RAD_S * supply_frac);
    out[2] = (double)u16(t, AX12_TORQUE_LIMIT) * AX12_LOAD_UNIT * supply_frac;
    out[3] = t[AX12_TORQUE_ENABLE] != 0;
    for (int k = 0; k < 4; k++)
        out[4 + k] = m[k];
    out[8] = u16(t, AX12_PUNCH);
}

/* Servo i's set-point to its joint (Servo._command) */
static void command(const struct bank *b, int i)
{
    double sp[9];
    int j = b->joint[i];
    hx_setpoint(b->position_rad, b->speed_rad_s, b->table[i], b->health[i]->supply_frac, sp);
    if (sp[0] != sp[0]) {
        double state[3];
        b->state(b->drives, j, state);
        sp[0] = state[0];
    }
    b->command(b->drives, j, sp[0], sp[1], sp[2], sp[3] != 0, sp + 4);
}

/* The health rule (health.py ServoHealth: its advance and errors call these) */
void hx_health_advance(struct health *h, int64_t dt_us, double load, int torque_limit)
{
    if (torque_limit && fabs(load) * 1023.0 >= (double)torque_limit * h->supply_frac - 0.5) {
        h->saturated_us += dt_us;
        if (h->saturated_us >= HEALTH_OVERLOAD_US)
            h->overload = 1;
    } else {
        h->saturated_us = 0;
    }
    double target, tau;
    if (h->hot) {
        target = h->hot_spot_c;
        tau = HEALTH_OVERHEAT_TAU_S;
    } else {
        target = HEALTH_AMBIENT_C + HEALTH_HEAT_C * load * load;
        tau = HEALTH_THERMAL_TAU_S;
    }
    if (target != h->temperature_c) {
        double k = exp((double)(-dt_us) * 1e-6 / tau);
        double c = target + (h->temperature_c - target) * k;
        int64_t units = (int64_t)rint(c);   /* Python's round: half to even */
        h->temperature_c = c;
        h->temperature_units = units < 0 ? 0 : (units > 255 ? 255 : (int32_t)units);
    }
}

int hx_health_errors(const struct health *h, const unsigned char *t)
{
    int e = 0;
    int v = h->voltage_units;
    if (v < t[AX12_MIN_VOLTAGE_LIMIT] || v > t[AX12_MAX_VOLTAGE_LIMIT])
        e |= DXL_ERR_INPUT_VOLTAGE;
    if (h->temperature_units > t[AX12_TEMPERATURE_LIMIT])
        e |= DXL_ERR_OVERHEATING;
    if (h->overload)
        e |= DXL_ERR_OVERLOAD;
    return e;
}

/* Servo.advance_to's health: dt_us at load against the table's torque limit (0 with
 * torque off), then the error bits for its limits */
int hx_health_step(struct health *h, int64_t dt_us, double load, const unsigned char *t)
{
    hx_health_advance(h, dt_us, load, t[AX12_TORQUE_ENABLE] ? u16(t, AX12_TORQUE_LIMIT) : 0);
    return hx_health_errors(h, t);
}

/* ServoHealth.rearm: Torque Limit written again (or power back) clears the overload */
void hx_rearm(struct health *h)
{
    h->overload = 0;
    h->saturated_us = 0;
}

/* Servo._alarm: the error bits' Alarm LED and alarm shutdown (Torque Limit to 0, e-manual
 * address 34); whether the drive must be commanded again */
int hx_alarm(struct servo *s, unsigned char *t, int errors)
{
    if (errors & t[AX12_ALARM_LED])
        s->alarm_led = 1;
    if ((errors & t[AX12_SHUTDOWN]) && (t[AX12_TORQUE_LIMIT] || t[AX12_TORQUE_LIMIT + 1])) {
        t[AX12_TORQUE_LIMIT] = 0;
        t[AX12_TORQUE_LIMIT + 1] = 0;
        s->present_stale = 1;
        return 1;
    }
    return 0;
}

/* Servo.advance_to once the horn is there: dt_us of the health at load, the Present
 * registers stale, the alarm; whether the drive must be commanded again */
int hx_catch_up(struct servo *s, struct health *h, unsigned char *t, int64_t dt_us, double load)
{
    int errors = hx_health_step(h, dt_us, load, t);
    s->present_stale = 1;
    return errors ? hx_alarm(s, t, errors) : 0;
}

/* advance_to for servo i behind t_us (the world is already there) */
static void advance(const struct bank *b, int i, int64_t t_us)
{
    struct servo *s = b->servo[i];
    int64_t dt = t_us - s->t_us;
    if (dt <= 0)
        return;
    s->t_us = t_us;
    double state[3];
    b->state(b->drives, b->joint[i], state);
    if (hx_catch_up(s, b->health[i], b->table[i], dt, state[2]))
        command(b, i);
}

/* A WRITE's check (ax12_servo.py Servo.check_write calls it; a SYNC_WRITE acts on its Range
 * bit alone): the error bits a write of d[0..n) at a earns on table t. cells: each
 * address's field; original: the 2006 manual's Lock rule. */
int hx_check_write(const struct cell *cells, int original, const unsigned char *t, int a,
                   const unsigned char *d, int n)
{
    int end = a + n;
    if (end > AX12_TABLE_SIZE)
        return DXL_ERR_RANGE;
    if (t[AX12_LOCK]) {
        if (original) {
            if (a < AX12_TORQUE_ENABLE || end > AX12_PRESENT_POSITION)
                return DXL_ERR_RANGE;
        } else if (a < AX12_EEPROM_END
                   || (a <= AX12_LOCK && AX12_LOCK < end && d[AX12_LOCK - a] == 0)) {
            return DXL_ERR_RANGE;     /* unlocked only by a power cycle */
        }
    }
    int w = wheel(t), error = 0;
    for (int c = a; c < end;) {
        const struct cell *f = &cells[c];
        if (f->start < 0 || !f->writable)
            return DXL_ERR_RANGE;
        int start = f->start;
        int lo = start >= a ? d[start - a] : t[start];
        int v = lo;
        if (f->size == 2) {
            int hi_i = start + 1;
            v = lo | ((hi_i < end ? d[hi_i - a] : t[hi_i]) << 8);
        }
        if (v < f->lo || v > ((start == AX12_MOVING_SPEED && w) ? 2047 : f->hi))
            return DXL_ERR_RANGE;
        /* a goal outside CW..CCW is stored, the horn stops at the limit */
        if (start == AX12_GOAL_POSITION && !w
                && (v < u16(t, AX12_CW_ANGLE_LIMIT) || v > u16(t, AX12_CCW_ANGLE_LIMIT)))
            error |= DXL_ERR_ANGLE_LIMIT;
        c = start + f->size;
    }
    return error;
}

/* Servo._apply_write: data d[0..n) written at a (checked: hx_check_write); the
 * HX_APPLY_ bits of what follows (the ID or Baud Rate changed, the drive to command) */
int hx_apply(struct servo *s, struct health *h, unsigned char *t, int a, const unsigned char *d,
             int n)
{
    int end = a + n, out = 0;
    memcpy(t + a, d, (size_t)n);
    if (a < AX12_EEPROM_END)
        s->busy_until_us = s->t_us + s->eeprom_busy_us;
    if (a <= AX12_BAUD_RATE && end > AX12_ID) {
        s->address_changed = 1;
        out |= HX_APPLY_ADDRESS;
    }
    if (a <= AX12_TORQUE_LIMIT + 1 && end > AX12_TORQUE_LIMIT)
        hx_rearm(h);   /* writing Torque Limit again re-arms the servo */
    if ((end > AX12_TORQUE_ENABLE && a < AX12_PRESENT_POSITION) || end > AX12_PUNCH
        || (a <= AX12_CCW_ANGLE_LIMIT + 1 && end > AX12_CW_ANGLE_LIMIT)) {
        s->present_stale = 1;
        out |= HX_APPLY_COMMAND;
    }
    return out;
}

/* A SYNC_WRITE's parameters p[0..len) (address, data length, then each ID and its data)
 * to one servo (Servo._sync_write): its ID's first entry, checked (a Range error refuses
 * it: a broadcast has no status) and applied; hx_apply's bits, 0 when the packet has no
 * entry for it or is malformed */
int hx_sync_one(struct servo *s, struct health *h, unsigned char *t, const struct cell *cells,
                int original, const unsigned char *p, int len)
{
    if (len < 2 || !p[1] || (len - 2) % (p[1] + 1))
        return 0;
    int a = p[0], n = p[1];
    for (int k = 2; k < len; k += n + 1) {
        if (p[k] != t[AX12_ID])
            continue;
        if (hx_check_write(cells, original, t, a, p + k + 1, n) & DXL_ERR_RANGE)
            return 0;
        return hx_apply(s, h, t, a, p + k + 1, n);
    }
    return 0;
}

/* TableServo._take where nothing holds the instruction back (hx_serves: no EEPROM write
 * under way, not deaf): catch up to t_us and count it */
static void take(const struct bank *b, int i, int64_t t_us)
{
    advance(b, i, t_us);
    b->servo[i]->held_us = 0;
    b->servo[i]->instructions += 1;
}

/* Servos from..n-1 take the SYNC_WRITE ``params`` at t_us, in order; returns the index of
 * the first one this cannot serve (not a world's joint, deaf, or finishing an EEPROM write:
 * the Python code serves it, then calls again from the next), or n when all are done;
 * ``*changed`` set when one's ID or Baud Rate changed (the line re-indexes). */
int hx_sync_write(const struct bank *b, int from, int64_t t_us, const unsigned char *p, int len,
                  int32_t *changed)
{
    for (int i = from; i < b->n; i++) {
        struct servo *s = b->servo[i];
        if (!hx_serves(b, i, t_us) || u16(b->table[i], AX12_MOVING_SPEED) > 2047)
            return i;
        take(b, i, t_us);
        int done = hx_sync_one(s, b->health[i], b->table[i], b->cells, b->original[i], p, len);
        if (done & HX_APPLY_ADDRESS)
            *changed = 1;
        if (done & HX_APPLY_COMMAND)
            command(b, i);
    }
    return b->n;
}

/* Servo._refresh_present: the Present registers of table t for the horn at pos_rad,
 * vel_rad_s and load (a fraction of stall torque) and health h, through
 * protocol/dynamixel/ax12.py's conversions (rad_to_position, rad_s_to_signed,
 * fraction_to_load); returns Present Position's value (a reading fault's input) */
int hx_present(unsigned char *t, const struct health *h, double pos_rad, double vel_rad_s,
               double load)
{
    /* math.degrees is x * (180 / pi) */
    int64_t p = py_round((pos_rad * (180.0 / M_PI) + AX12_POSITION_CENTRE_DEG) * AX12_POSITION_MAX
                         / AX12_POSITION_RANGE_DEG);
    p = p < 0 ? 0 : (p > AX12_POSITION_MAX ? AX12_POSITION_MAX : p);
    t[AX12_PRESENT_POSITION] = (unsigned char)(p & 0xFF);
    t[AX12_PRESENT_POSITION + 1] = (unsigned char)(p >> 8);
    int64_t v = py_round(fabs(vel_rad_s) * 60.0 / (2.0 * M_PI) / AX12_SPEED_UNIT);
    v = v > 1023 ? 1023 : v;
    if (vel_rad_s < 0 && v)
        v |= AX12_DIRECTION_BIT;
    t[AX12_PRESENT_SPEED] = (unsigned char)(v & 0xFF);
    t[AX12_PRESENT_SPEED + 1] = (unsigned char)(v >> 8);
    int64_t ld = py_round(fabs(load) / AX12_LOAD_UNIT);
    ld = ld > 1023 ? 1023 : ld;
    if (load < 0 && ld)
        ld |= AX12_DIRECTION_BIT;
    t[AX12_PRESENT_LOAD] = (unsigned char)(ld & 0xFF);
    t[AX12_PRESENT_LOAD + 1] = (unsigned char)(ld >> 8);
    t[AX12_PRESENT_VOLTAGE] = (unsigned char)h->voltage_units;
    t[AX12_PRESENT_TEMPERATURE] = (unsigned char)h->temperature_units;
    t[AX12_MOVING] = fabs(vel_rad_s) >= MOVING_EPS_RAD_S;
    return (int)p;
}

/* Servo._answer: the status packet to instruction code (its error bits with the health's,
 * data d[0..n)) into out when the Status Return Level answers it (2: every instruction; 1:
 * READ and PING; 0: PING alone); its length, 0 when the servo answers nothing */
int hx_answer(const unsigned char *t, const struct health *h, int code, int error,
              const unsigned char *d, int n, unsigned char *out)
{
    int srl = t[AX12_STATUS_RETURN_LEVEL];
    if (!(srl >= 2 || code == DXL_PING || (srl == 1 && code == DXL_READ)))
        return 0;
    int bits = error | hx_health_errors(h, t);
    int sum = t[AX12_ID] + n + 2 + bits;
    out[0] = out[1] = 0xFF;
    out[2] = t[AX12_ID];
    out[3] = (unsigned char)(n + 2);
    out[4] = (unsigned char)bits;
    for (int k = 0; k < n; k++) {
        out[5 + k] = d[k];
        sum += d[k];
    }
    out[5 + n] = (unsigned char)(~sum & 0xFF);
    return n + 6;
}

/* A READ of n bytes at a to one servo after its catch-up (Servo._read): the data (the
 * Present registers brought up to date from the horn's state, pos_rad, vel_rad_s and load,
 * when stale), the alarms, and the status packet into out (room for TABLE_SIZE + 6) unless
 * broadcast or below Status Return Level 1 (Servo._answer). Returns the packet's length (0:
 * no answer), plus HX_READ_COMMAND when an alarm shutdown must command the drive; or
 * HX_READ_REFRESH alone, having done nothing, when the registers are stale and state is
 * NULL (a Present Position fault: the caller refreshes them its way and calls again). */
int hx_read_one(struct servo *s, struct health *h, unsigned char *t, int a, int n, int broadcast,
                const double *state, unsigned char *out)
{
    int error = 0, len = 0, done = 0;
    unsigned char data[AX12_TABLE_SIZE];
    if (a + n > AX12_TABLE_SIZE || n == 0) {
        error = DXL_ERR_RANGE;
    } else {
        if (s->present_stale) {
            if (state == NULL)
                return HX_READ_REFRESH;
            hx_present(t, h, state[0], state[1], state[2]);
            s->present_stale = 0;
        }
        memcpy(data, t + a, (size_t)n);
        len = n;
    }
    int alarms = error | hx_health_errors(h, t);   /* a limit just written may be exceeded */
    if (alarms && hx_alarm(s, t, alarms))
        done = HX_READ_COMMAND;
    return broadcast ? done : hx_answer(t, h, DXL_READ, error, data, len, out) | done;
}

/* A READ (its two parameters a, n) to servo i of the bank at t_us: the status packet into
 * out (room for 56 bytes), its length, 0 when the servo answers nothing, -1 when the
 * Python code must serve it (not a world's joint, deaf, finishing an EEPROM write). */
int hx_read(const struct bank *b, int i, int64_t t_us, int a, int n, unsigned char *out)
{
    struct servo *s = b->servo[i];
    if (!hx_serves(b, i, t_us))
        return -1;
    take(b, i, t_us);
    double state[3];
    b->state(b->drives, b->joint[i], state);
    int done = hx_read_one(s, b->health[i], b->table[i], a, n, 0, state, out);
    if (done & HX_READ_COMMAND)
        command(b, i);
    return done & HX_READ_LEN;
}

/* An AX-12's state_row (ax12_servo.py Servo.state_row), as the recorder logs it on
 * /servos: id, the horn's state (its true angle, speed and load), temperature, voltage,
 * torque enabled, moving, the error bits; packed little-endian "<Bddddd??B", STATE_ROW
 * bytes (servo_layout.py; unpacked where the recorder encodes them). */
void hx_state_row(const unsigned char *t, const struct health *h, const double *state,
                  unsigned char *out)
{
    out[0] = t[AX12_ID];
    memcpy(out + 1, state, 24);
    memcpy(out + 25, &h->temperature_c, 8);
    memcpy(out + 33, &h->supply_v, 8);
    out[41] = t[AX12_TORQUE_ENABLE] != 0;
    out[42] = fabs(state[1]) >= MOVING_EPS_RAD_S;
    out[43] = (unsigned char)hx_health_errors(h, t);
}

/* The state_row of every servo of the bank (each on a world's joint: the Python code
 * checks), one after the other */
void hx_state_rows(const struct bank *b, unsigned char *out)
{
    for (int i = 0; i < b->n; i++, out += STATE_ROW) {
        double state[3];
        b->state(b->drives, b->joint[i], state);
        hx_state_row(b->table[i], b->health[i], state, out);
    }
}
