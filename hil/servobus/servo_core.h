/* The compiled servo bank's state, shared by servo_core.c (the servos' SYNC_WRITE and READ)
 * and reads_core.c (a cycle's status reads on the line). Its structs and the protocol's
 * constants are servo_layout.h, which setup.py writes from hil/servobus/servo_layout.py. */
#ifndef HX_SERVO_CORE_H
#define HX_SERVO_CORE_H
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "servo_layout.h"

/* Whether the C code serves servo i at t_us: a MuJoCo joint, neither deaf nor finishing
 * an EEPROM write (any other is left to its Python handle) */
static inline int hx_serves(const struct bank *b, int i, int64_t t_us)
{
    const struct servo *s = b->servo[i];
    return b->joint[i] >= 0 && s->busy_until_us <= t_us && s->deaf_until_us <= t_us;
}

/* servo_core.c: the health rule, health.py ServoHealth's advance and errors */
void hx_health_advance(struct health *h, int64_t dt_us, double load, int torque_limit);
int hx_health_errors(const struct health *h, const unsigned char *t);
int hx_health_step(struct health *h, int64_t dt_us, double load, const unsigned char *t);

/* servo_core.c: a WRITE's check, ax12_servo.py Servo.check_write */
int hx_check_write(const struct cell *cells, int original, const unsigned char *t, int a,
                   const unsigned char *d, int n);

/* servo_core.c: a READ (parameters a, n) to servo i at t_us, answered into out */
int hx_read(const struct bank *b, int i, int64_t t_us, int a, int n, unsigned char *out);

/* servo_core.c: a broadcast SYNC_WRITE's parameters p to the servos from ``from`` on; the
 * index of the first left to its Python handle, or n */
int hx_sync_write(const struct bank *b, int from, int64_t t_us, const unsigned char *p, int len,
                  int32_t *changed);

#endif
