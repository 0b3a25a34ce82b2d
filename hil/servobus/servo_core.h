/* The compiled servo bank's state, shared by servo_core.c (the servos' SYNC_WRITE and READ)
 * and reads_core.c (a cycle's status reads on the line). Its structs and the protocol's
 * constants are servo_layout.h, which setup.py writes from hil/servobus/servo_layout.py. */
#ifndef HX_SERVO_CORE_H
#define HX_SERVO_CORE_H
#include <math.h>
#include <stdint.h>
#include <string.h>

/* the seam to the joints a bank drives (hil/world/drive_core.c hx_state and hx_command):
 * joint j's angle, speed and load; its set-point, compliance NULL: unchanged */
typedef void (*hx_state_fn)(const void *drives, int j, double *out);
typedef void (*hx_command_fn)(void *drives, int j, double goal_rad, double speed_rad_s,
                              double torque, int enabled, const double *compliance);

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

/* servo_core.c: the rest of ax12_servo.py Servo's rules (servo_rules.py binds them) */
void hx_setpoint(const double *position_rad, const double *speed_rad_s, const unsigned char *t,
                 double supply_frac, double *out);
void hx_rearm(struct health *h);
int hx_alarm(struct servo *s, unsigned char *t, int errors);
int hx_catch_up(struct servo *s, struct health *h, unsigned char *t, int64_t dt_us, double load);
int hx_apply(struct servo *s, struct health *h, unsigned char *t, int a, const unsigned char *d,
             int n);
int hx_present(unsigned char *t, const struct health *h, double pos_rad, double vel_rad_s,
               double load);
int hx_answer(const unsigned char *t, const struct health *h, int code, int error,
              const unsigned char *d, int n, unsigned char *out);
int hx_read_one(struct servo *s, struct health *h, unsigned char *t, int a, int n, int broadcast,
                const double *state, unsigned char *out);
void hx_state_row(const unsigned char *t, const struct health *h, const double *state,
                  unsigned char *out);
int hx_sync_one(struct servo *s, struct health *h, unsigned char *t, const struct cell *cells,
                int original, const unsigned char *p, int len);

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
