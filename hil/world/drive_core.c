/* The drive bank's per-step arithmetic (hil/world/actuator.py DriveBank.duty_for) for all
 * joints in one call, its one implementation: numpy's element-wise semantics (NaN through
 * minimum and maximum, sign of zero), the operations in the order the recorded traces
 * were made with (built with -ffp-contract=off: no fused multiply-add). Loaded by hil/world/drive_core.py; built by setup.py, which writes
 * the struct's header from hil/world/drive_layout.py. */
#include <math.h>
#include <stddef.h>

#include "drive_layout.h"

const char hx_layout[] = HX_LAYOUT;

/* Advance the set-points by one step of dt_s; the signed duties on the angles q into
 * b->duty and, when ctrl is not NULL, stall * duty into ctrl. */
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
