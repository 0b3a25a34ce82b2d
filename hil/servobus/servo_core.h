/* The compiled servo bank's state, shared by servo_core.c (the servos' SYNC_WRITE and READ)
 * and reads_core.c (a cycle's status reads on the line): the layouts of the ctypes
 * structures hil/servobus/servo_core.py builds. */
#ifndef HX_SERVO_CORE_H
#define HX_SERVO_CORE_H
#include <math.h>
#include <stdint.h>
#include <string.h>

/* hil/servobus/health.py ServoHealth's fields, in its _fields_ order */
struct health {
    double supply_v, supply_frac, temperature_c, hot_spot_c;
    int64_t saturated_us;
    int32_t voltage_units, temperature_units;
    uint8_t overload, hot;
};

/* hil/servobus/ax12_servo.py Servo's fields, in its _fields_ order */
struct servo {
    int64_t t_us, busy_until_us, deaf_until_us, held_us, held, instructions, ignored,
        eeprom_busy_us;
    uint8_t alarm_led, address_changed, present_stale;
};

/* one control-table cell's field, from protocol/dynamixel/ax12.py (start < 0: reserved) */
struct cell {
    int32_t start, size, lo, hi, writable;
};

struct bank {
    int n;
    struct servo **servo;
    struct health **health;
    unsigned char **table;
    const int32_t *joint;          /* the servo's joint in the world; -1: not a MuJoCo joint */
    const int32_t *original;       /* the 2006 manual's Lock rule */
    const struct cell *cells;      /* 50 */
    const double *position_rad;    /* 1024: drive.py _POSITION_RAD */
    const double *speed_rad_s;     /* 2048: drive.py _SPEED_RAD_S */
    /* the world: joint state (read) and the drive bank (written) */
    const double *q, *qd, *duty, *offset;
    double *goal, *setpoint, *speed, *torque_limit, *margin, *slope, *punch, *compliance;
    unsigned char *enabled;
    int joints;                    /* the drive bank's size: margin and slope rows */
    double motor_no_load, ax12_no_load, speed_unit, load_unit, position_unit, punch_unit,
        moving_eps;
    /* health.py constants */
    double ambient_c, heat_c, thermal_tau_s, overheat_tau_s;
    int64_t overload_us;
};

/* Whether the C code serves servo i at t_us: a MuJoCo joint, neither deaf nor finishing
 * an EEPROM write (any other is left to its Python handle) */
static inline int hx_serves(const struct bank *b, int i, int64_t t_us)
{
    const struct servo *s = b->servo[i];
    return b->joint[i] >= 0 && s->busy_until_us <= t_us && s->deaf_until_us <= t_us;
}

/* servo_core.c: a READ (parameters a, n) to servo i at t_us, answered into out */
int hx_read(const struct bank *b, int i, int64_t t_us, int a, int n, unsigned char *out);

/* servo_core.c: a broadcast SYNC_WRITE's parameters p to the servos from ``from`` on; the
 * index of the first left to its Python handle, or n */
int hx_sync_write(const struct bank *b, int from, int64_t t_us, const unsigned char *p, int len,
                  int32_t *changed);

#endif
