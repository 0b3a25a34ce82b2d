/* The AX-12s' two instructions of every cycle: a SYNC_WRITE carried out by every servo on
 * the line in one call, what hil/servobus/ax12_servo.py's Servo.handle does for each of them
 * (catch up its health to the packet's time, look its ID up in the packet, check the write
 * against its control table, apply it and hand the set-point to its MuJoCo joint,
 * hil/world/actuator.py), and a READ answered with its status packet. The same
 * IEEE operations in the same order, so the tables, the drives and the trace are the same
 * bits (built with -ffp-contract=off: no fused multiply-add; exp and rint are the C
 * library's, which CPython's math.exp and round call too). The servos' state lives in
 * ctypes structures the Python code reads and writes as attributes (servo_core.py).
 * Loaded by hil/servobus/servo_core.py; built by setup.py, which writes servo_layout.h (the
 * structs and the protocol's constants) from hil/servobus/servo_layout.py. */
#include "servo_core.h"

const char hx_layout[] = HX_LAYOUT;   /* checked at load (hil/native.py) */

/* Python's min(a, b) and max(a, b): the first unless the second is strictly beyond it */
static double py_min(double a, double b) { return b < a ? b : a; }
static double py_max(double a, double b) { return b > a ? b : a; }

static int u16(const unsigned char *t, int a) { return t[a] | (t[a + 1] << 8); }
static int wheel(const unsigned char *t)   /* both angle limits 0 */
{
    return !(u16(t, AX12_CW_ANGLE_LIMIT) || u16(t, AX12_CCW_ANGLE_LIMIT));
}

/* MujocoActuator.state()[0] and [2] */
static double present_rad(const struct bank *b, int j) { return b->q[j] + b->offset[j]; }
static double load_frac(const struct bank *b, int j)
{
    double load = b->duty[j] - b->qd[j] / b->motor_no_load;
    return py_max(-1.0, py_min(1.0, load));
}

/* drive.py drive() into MujocoActuator.command() */
static void command(const struct bank *b, const unsigned char *t, double supply_frac, int j)
{
    int speed = u16(t, AX12_MOVING_SPEED);
    double goal_rad, speed_rad_s;
    if (wheel(t)) {
        int mag = speed & 0x3FF;
        if (mag)
            goal_rad = (speed & 0x400) ? -INFINITY : INFINITY;
        else
            goal_rad = present_rad(b, j);
        speed_rad_s = (double)mag * b->speed_unit * 2.0 * M_PI / 60.0;
    } else {
        int cw = u16(t, AX12_CW_ANGLE_LIMIT), ccw = u16(t, AX12_CCW_ANGLE_LIMIT),
            goal = u16(t, AX12_GOAL_POSITION);
        goal_rad = b->position_rad[goal < cw ? cw : (goal > ccw ? ccw : goal)];
        speed_rad_s = b->speed_rad_s[speed];
    }
    double limit = py_min(speed_rad_s, b->ax12_no_load * supply_frac);
    double torque = (double)u16(t, AX12_TORQUE_LIMIT) * b->load_unit * supply_frac;
    int enabled = t[AX12_TORQUE_ENABLE] != 0;
    if (enabled && !b->enabled[j])
        b->setpoint[j] = present_rad(b, j);   /* resume from where it reads */
    b->goal[j] = goal_rad;
    b->speed[j] = limit > 0 ? limit : b->motor_no_load;
    b->torque_limit[j] = py_min(py_max(torque, 0.0), 1.0);
    b->enabled[j] = (unsigned char)enabled;
    const unsigned char *m = t + AX12_CW_COMPLIANCE_MARGIN;   /* CW, CCW margin; CW, CCW slope */
    double c[5] = {m[0], m[1], m[2], m[3], u16(t, AX12_PUNCH)};
    double *seen = b->compliance + 5 * j;
    if (memcmp(c, seen, sizeof c) != 0 || seen[0] != seen[0]) {   /* DriveBank.set_compliance */
        int n = b->joints;
        b->margin[j] = c[0] * b->position_unit;
        b->margin[n + j] = c[1] * b->position_unit;
        b->slope[j] = py_max(c[2], 1.0) * b->position_unit;
        b->slope[n + j] = py_max(c[3], 1.0) * b->position_unit;
        b->punch[j] = c[4] * b->punch_unit;
        memcpy(seen, c, sizeof c);
    }
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

/* Servo._alarm: the error bits' LED and shutdown (the torque limit to 0) */
static void alarm(const struct bank *b, int i, int errors)
{
    if (!errors)
        return;
    struct servo *s = b->servo[i];
    unsigned char *t = b->table[i];
    if (errors & t[AX12_ALARM_LED])
        s->alarm_led = 1;
    if ((errors & t[AX12_SHUTDOWN]) && (t[AX12_TORQUE_LIMIT] || t[AX12_TORQUE_LIMIT + 1])) {
        t[AX12_TORQUE_LIMIT] = 0;
        t[AX12_TORQUE_LIMIT + 1] = 0;
        command(b, t, b->health[i]->supply_frac, b->joint[i]);
        s->present_stale = 1;
    }
}

/* Servo.advance_to for a servo behind t_us (the world is already there) */
static void advance(const struct bank *b, int i, int64_t t_us)
{
    struct servo *s = b->servo[i];
    int64_t dt = t_us - s->t_us;
    if (dt <= 0)
        return;
    s->t_us = t_us;
    int errors = hx_health_step(b->health[i], dt, load_frac(b, b->joint[i]), b->table[i]);
    s->present_stale = 1;
    alarm(b, i, errors);
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

/* Servo._apply_write; returns whether the ID or Baud Rate changed */
static int apply(const struct bank *b, int i, int a, const unsigned char *d, int n)
{
    struct servo *s = b->servo[i];
    unsigned char *t = b->table[i];
    int end = a + n;
    memcpy(t + a, d, (size_t)n);
    if (a < AX12_EEPROM_END)
        s->busy_until_us = s->t_us + s->eeprom_busy_us;
    int changed = a <= AX12_BAUD_RATE && end > AX12_ID;
    if (changed)
        s->address_changed = 1;
    if (a <= AX12_TORQUE_LIMIT + 1 && end > AX12_TORQUE_LIMIT) {   /* ServoHealth.rearm */
        b->health[i]->overload = 0;
        b->health[i]->saturated_us = 0;
    }
    if ((end > AX12_TORQUE_ENABLE && a < AX12_PRESENT_POSITION) || end > AX12_PUNCH
        || (a <= AX12_CCW_ANGLE_LIMIT + 1 && end > AX12_CW_ANGLE_LIMIT)) {
        command(b, t, b->health[i]->supply_frac, b->joint[i]);
        s->present_stale = 1;
    }
    return changed;
}

/* Servos from..n-1 take the SYNC_WRITE ``params`` at t_us, in order; returns the index of
 * the first one this cannot serve (not a MuJoCo joint, deaf, or finishing an EEPROM write:
 * the Python code serves it, then calls again from the next), or n when all are done;
 * ``*changed`` set when one's ID or Baud Rate changed (the line re-indexes). */
int hx_sync_write(const struct bank *b, int from, int64_t t_us, const unsigned char *p, int len,
                  int32_t *changed)
{
    int first[256];
    int a = -1, stride = 0;
    if (len >= 2 && p[1] && (len - 2) % (p[1] + 1) == 0) {   /* ax12_servo.sync_entries */
        a = p[0];
        stride = p[1] + 1;
        for (int k = 0; k < 256; k++)
            first[k] = -1;
        for (int k = 2; k < len; k += stride)
            if (first[p[k]] < 0)
                first[p[k]] = k + 1;
    }
    for (int i = from; i < b->n; i++) {
        struct servo *s = b->servo[i];
        if (!hx_serves(b, i, t_us) || u16(b->table[i], AX12_MOVING_SPEED) > 2047)
            return i;
        advance(b, i, t_us);                /* TableServo._take, nothing to wait for */
        s->held_us = 0;
        s->instructions += 1;
        if (a < 0)
            continue;
        int at = first[b->table[i][AX12_ID]];
        if (at < 0 || (hx_check_write(b->cells, b->original[i], b->table[i], a, p + at,
                                      stride - 1) & DXL_ERR_RANGE))
            continue;
        if (apply(b, i, a, p + at, stride - 1))
            *changed = 1;
    }
    return b->n;
}

/* Python's int(round(x)) for the finite values below: half to even */
static int64_t py_round(double x) { return (int64_t)rint(x); }

/* Servo._refresh_present through protocol/dynamixel/ax12.py's conversions (no reading fault:
 * the Python code serves a servo with one) */
static void refresh_present(const struct bank *b, int i)
{
    unsigned char *t = b->table[i];
    const struct health *h = b->health[i];
    int j = b->joint[i];
    double pos = present_rad(b, j), vel = b->qd[j], load = load_frac(b, j);
    /* rad_to_position: math.degrees is x * (180 / pi) */
    int64_t p = py_round((pos * (180.0 / M_PI) + AX12_POSITION_CENTRE_DEG) * AX12_POSITION_MAX
                         / AX12_POSITION_RANGE_DEG);
    p = p < 0 ? 0 : (p > AX12_POSITION_MAX ? AX12_POSITION_MAX : p);
    t[AX12_PRESENT_POSITION] = (unsigned char)(p & 0xFF);
    t[AX12_PRESENT_POSITION + 1] = (unsigned char)(p >> 8);
    int64_t v = py_round(fabs(vel) * 60.0 / (2.0 * M_PI) / b->speed_unit);   /* rad_s_to_signed */
    v = v > 1023 ? 1023 : v;
    if (vel < 0 && v)
        v |= AX12_DIRECTION_BIT;
    t[AX12_PRESENT_SPEED] = (unsigned char)(v & 0xFF);
    t[AX12_PRESENT_SPEED + 1] = (unsigned char)(v >> 8);
    int64_t ld = py_round(fabs(load) / b->load_unit);                       /* fraction_to_load */
    ld = ld > 1023 ? 1023 : ld;
    if (load < 0 && ld)
        ld |= AX12_DIRECTION_BIT;
    t[AX12_PRESENT_LOAD] = (unsigned char)(ld & 0xFF);
    t[AX12_PRESENT_LOAD + 1] = (unsigned char)(ld >> 8);
    t[AX12_PRESENT_VOLTAGE] = (unsigned char)h->voltage_units;
    t[AX12_PRESENT_TEMPERATURE] = (unsigned char)h->temperature_units;
    t[AX12_MOVING] = fabs(vel) >= b->moving_eps;
    b->servo[i]->present_stale = 0;
}

/* Servo.handle of a READ (its two parameters a, n) to servo i at t_us: the status packet
 * into out (room for 56 bytes), its length, 0 when the servo answers nothing, -1 when the
 * Python code must serve it (not a MuJoCo joint, deaf, finishing an EEPROM write). */
int hx_read(const struct bank *b, int i, int64_t t_us, int a, int n, unsigned char *out)
{
    struct servo *s = b->servo[i];
    if (!hx_serves(b, i, t_us))
        return -1;
    advance(b, i, t_us);
    s->held_us = 0;
    s->instructions += 1;
    unsigned char *t = b->table[i];
    int error = 0, len = 0;
    unsigned char data[AX12_TABLE_SIZE];
    if (a + n > AX12_TABLE_SIZE || n == 0) {
        error = DXL_ERR_RANGE;
    } else {
        if (s->present_stale)
            refresh_present(b, i);
        memcpy(data, t + a, (size_t)n);
        len = n;
    }
    alarm(b, i, error | hx_health_errors(b->health[i], t));
    if (t[AX12_STATUS_RETURN_LEVEL] < 1)   /* Servo._answer: a READ is answered from level 1 */
        return 0;
    int code = error | hx_health_errors(b->health[i], t);
    int sum = t[AX12_ID] + len + 2 + code;
    out[0] = out[1] = 0xFF;
    out[2] = t[AX12_ID];
    out[3] = (unsigned char)(len + 2);
    out[4] = (unsigned char)code;
    for (int k = 0; k < len; k++) {
        out[5 + k] = data[k];
        sum += data[k];
    }
    out[5 + len] = (unsigned char)(~sum & 0xFF);
    return len + 6;
}

/* TableServo.state_row of every servo of the bank (each on a MuJoCo joint: the Python code
 * checks), as the recorder logs it on /servos: id, Present Position's true angle, speed,
 * load (MujocoActuator.state), temperature, voltage, torque enabled, moving (drive.py
 * is_moving), the error bits (ServoHealth.errors); packed little-endian "<Bddddd??B",
 * STATE_ROW bytes a servo (servo_layout.py; servo_core.py unpacks them where the recorder
 * encodes). */

void hx_state_rows(const struct bank *b, unsigned char *out)
{
    for (int i = 0; i < b->n; i++, out += STATE_ROW) {
        const unsigned char *t = b->table[i];
        const struct health *h = b->health[i];
        int j = b->joint[i];
        double pos = present_rad(b, j), vel = b->qd[j], load = load_frac(b, j);
        out[0] = t[AX12_ID];
        memcpy(out + 1, &pos, 8);
        memcpy(out + 9, &vel, 8);
        memcpy(out + 17, &load, 8);
        memcpy(out + 25, &h->temperature_c, 8);
        memcpy(out + 33, &h->supply_v, 8);
        out[41] = t[AX12_TORQUE_ENABLE] != 0;
        out[42] = fabs(vel) >= b->moving_eps;
        out[43] = (unsigned char)hx_health_errors(h, t);
    }
}
