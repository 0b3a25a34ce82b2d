/* The drive bank (hil/world/actuator.py DriveBank and MujocoActuator), its one
 * implementation: a joint's command and compliance, its state as a servo reads it, and
 * every joint's per-step duty in one call. numpy's element-wise semantics (NaN through
 * minimum and maximum, sign of zero) and Python's min and max, the operations in the
 * order the recorded traces were made with (built with -ffp-contract=off: no fused
 * multiply-add). The compiled servo bank (hil/servobus/servo_core.c) calls hx_command and
 * hx_state through the pointers drive_core.py hands it. Loaded by hil/world/drive_core.py;
 * built by setup.py, which writes the struct's header from hil/world/drive_layout.py. */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "drive_layout.h"

const char hx_layout[] = HX_LAYOUT;

/* Python's min(a, b) and max(a, b): the first unless the second is strictly beyond it */
static double py_min(double a, double b) { return b < a ? b : a; }
static double py_max(double a, double b) { return b > a ? b : a; }

/* Joint j's angle as its servo's potentiometer reads it (with its zero offset) */
static double reading_rad(const struct bank *b, int j) { return b->q[j] + b->offset[j]; }

/* Joint j as its servo reads it: out[0] the angle (with the potentiometer's offset), [1]
 * the speed, [2] the load, a signed fraction of stall torque (the duty less back-EMF) */
void hx_state(const struct bank *b, int j, double *out)
{
    double v = b->qd[j];
    double load = b->duty[j] - v / b->motor_no_load;
    out[0] = reading_rad(b, j);
    out[1] = v;
    out[2] = py_max(-1.0, py_min(1.0, load));
}

/* The compliance registers c (CW, CCW margin; CW, CCW slope; punch, raw units) as joint
 * j's margins, slopes (a slope of 0 would be a step: the smallest is 1 unit) and punch */
void hx_compliance(struct bank *b, int j, const double *c)
{
    int n = b->n;
    b->margin[j] = c[0] * POSITION_UNIT_RAD;   /* row 0: CW (e < 0), row 1: CCW (e > 0) */
    b->margin[n + j] = c[1] * POSITION_UNIT_RAD;
    b->slope[j] = py_max(c[2], 1.0) * POSITION_UNIT_RAD;
    b->slope[n + j] = py_max(c[3], 1.0) * POSITION_UNIT_RAD;
    b->punch[j] = c[4] * PUNCH_PER_UNIT;
    memcpy(b->compliance + 5 * j, c, 5 * sizeof(double));
}

/* Joint j's servo commands it (the Actuator seam's command): a torque switched on resumes
 * from where the joint reads; a speed limit of 0 is the motor's no-load speed; the torque
 * limit is a fraction in [0, 1]; compliance (5 raw registers) NULL: unchanged. */
void hx_command(struct bank *b, int j, double goal_rad, double speed_rad_s, double torque,
                int enabled, const double *compliance)
{
    if (enabled && !b->enabled[j])
        b->setpoint[j] = reading_rad(b, j);
    b->goal[j] = goal_rad;
    b->speed[j] = speed_rad_s > 0 ? speed_rad_s : b->motor_no_load;
    b->torque_limit[j] = py_min(py_max(torque, 0.0), 1.0);
    b->enabled[j] = (unsigned char)(enabled != 0);
    const double *seen = b->compliance + 5 * j;
    if (compliance != NULL && (memcmp(compliance, seen, 5 * sizeof(double)) != 0
                               || seen[0] != seen[0]))
        hx_compliance(b, j, compliance);
}

/* Advance the set-points by one step of dt_s; the signed duties on the angles q into
 * b->duty and, when ctrl is not NULL, stall * duty into ctrl: the set-point moves toward
 * the goal by at most the speed limit's step; the duty is the error beyond the compliance
 * margin over the slope, plus punch, capped at the torque limit, signed as the error, zero
 * inside the margin or with torque off. */
void hx_duty(const struct bank *b, const double *q, double dt_s, double *ctrl, double stall)
{
    const int n = b->n;
    for (int i = 0; i < n; i++) {
        double step = b->speed[i] * dt_s;
        double d = b->goal[i] - b->setpoint[i];
        double nstep = -step;
        d = (d < step || d != d) ? d : step;              /* np.minimum(d, step) */
        d = (d > nstep || d != d) ? d : nstep;            /* np.maximum(d, -step) */
        double sp = b->setpoint[i] + d;
        b->setpoint[i] = sp;
        double e = sp - q[i];
        int ccw = e > 0;
        double excess = fabs(e);
        excess -= ccw ? b->margin[n + i] : b->margin[i];
        double u = excess / (ccw ? b->slope[n + i] : b->slope[i]);
        u += b->punch[i];
        double tl = b->torque_limit[i];
        u = (u < tl || u != u) ? u : tl;                  /* np.minimum(u, tl) */
        double sign = e > 0 ? 1.0 : (e < 0 ? -1.0 : (e == 0 ? 0.0 : e));   /* np.sign */
        double on = (excess > 0 && b->enabled[i]) ? 1.0 : 0.0;
        u *= sign * on;
        b->duty[i] = u;
        if (ctrl != NULL)
            ctrl[i] = stall * u;
    }
}
