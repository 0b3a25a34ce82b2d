"""Firmware defaults: the robot of seed 003 (Sec. 2.4, 3.1, 3.3) and the loop settings.

The simulator link may override any key at boot (``hal.config()``); the board uses these.
Lengths in metres, times in seconds unless the name says otherwise.
"""

# Leg order everywhere (CAN tactile bit i = leg i): seed 003 Fig. 13's abbreviations.
from protocol.can_frames import LEGS  # noqa: E402  (one leg order: CAN tactile bit i = leg i)

DEFAULTS = {
    # Control loop. 50 Hz: one cycle's bus work (SYNC_WRITE 0.98 ms + 3 reads of 0.2 ms)
    # is under 10 % of the 20 ms period at 1 Mbps.
    "cycle_hz": 50.0,
    "reads_per_cycle": 3,         # servos polled for present position/speed/load per cycle
    "read_retries": 1,            # retries of a status read that timed out or was corrupt
    "servo_lost_s": 3.0,          # no valid reply for this long -> safe stop (rides a 2 s loss)
    "critical_errors": 3,         # consecutive overload/overheat statuses -> safe stop
    "debounce_ms": 20,            # a switch level must hold this long to count
    "telemetry_hz": 10.0,         # heartbeat and periodic tactile frame
    "tactile": True,              # Eq. 5-7 obstacle rule on (False: the paper's baseline)
    "autostart": True,            # walk after boot without waiting for a CAN start command
    # Gait (Sec. 3.3): tripod 0.036 m/s and wave 0.013 m/s with l_i = 5 cm (Eq. 1 and 16:
    # L <= l_i = 5 cm); speed = l T / ((T - 1) period) gives the periods below.
    "gait": "tripod",
    "step_length_m": 0.05,        # l_i
    "step_height_m": 0.03,        # h_i ("usually set to minimum")
    "period_s": 0.05 * 2 / 0.036,  # tripod at 0.036 m/s: 2.78 s
    "max_obstacle_height_m": 0.05,  # H of Eq. 7 (Eq. 16: H <= 5 cm)
    "direction_deg": 0.0,         # epsilon of Eq. 2-3, 0 = forward (+x)
    # Bus.
    "servos": 18,
    "first_id": 1,
    "return_delay_us": 0,         # written to every servo at configure time
    "baud": 1000000,
}

# Gait periods that give the paper's speeds at l_i = 5 cm (seed 003 Sec. 3.3):
# tripod T = 2 at 0.036 m/s, wave T = 6 at 0.013 m/s.
PERIOD_FOR_GAIT_S = {"tripod": 0.05 * 2 / 0.036, "wave": 0.05 * 6 / (5 * 0.013)}


def merged(overrides):
    """DEFAULTS updated with ``overrides`` (unknown keys are an error, not ignored)."""
    out = dict(DEFAULTS)
    if overrides:
        for k in overrides:
            if k not in out:
                raise ValueError("unknown firmware config key %r" % k)
            out[k] = overrides[k]
    return out
