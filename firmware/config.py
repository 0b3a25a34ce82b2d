"""Firmware defaults: the loop settings and the gait it starts with (seed 003 Sec. 2.4, 3.3).

The simulator link may override any key at boot (``hal.config()``; the keys, types and
units are protocol/link_schema.py CONFIG); the board uses these.
The robot itself (geometry, gaits, the paper's speeds) is ``protocol/hexapod.py``.
Lengths in metres, times in seconds unless the name says otherwise.
"""
from protocol import hexapod
from protocol import link_schema as ls

DEFAULTS = {
    # Control loop. 50 Hz: one cycle's bus work (SYNC_WRITE 0.98 ms + 3 reads of 0.2 ms)
    # is under 10 % of the 20 ms period at 1 Mbps.
    ls.CYCLE_HZ: 50.0,
    ls.READS_PER_CYCLE: 3,         # servos polled for present position/speed/load per cycle
    ls.READ_RETRIES: 1,            # retries of a status read that timed out or was corrupt
    ls.SERVO_LOST_S: 3.0,          # no valid reply for this long -> safe stop (rides a 2 s loss)
    ls.CRITICAL_ERRORS: 3,         # consecutive overload/overheat statuses -> safe stop
    ls.DEBOUNCE_MS: 20,            # a switch level must hold this long to count
    ls.TELEMETRY_HZ: 10.0,         # heartbeat and periodic tactile frame
    ls.TACTILE_ON: ls.TACTILE_DEFAULT,  # Eq. 5-7 obstacle rule on (False: the paper's baseline)
    ls.AUTOSTART: True,            # walk after boot without waiting for a CAN start command
    # Gait (Sec. 3.3): the default gait at the paper's speed with l_i = 5 cm.
    ls.GAIT: hexapod.DEFAULT_GAIT,
    ls.STEP_LENGTH_M: hexapod.STEP_LENGTH_M,  # l_i
    ls.STEP_HEIGHT_M: 0.03,        # h_i ("usually set to minimum")
    ls.PERIOD_S: hexapod.GAIT_PERIOD_S[hexapod.DEFAULT_GAIT],  # tripod at 0.036 m/s: 2.78 s
    ls.MAX_OBSTACLE_HEIGHT_M: 0.05,  # H of Eq. 7 (Eq. 16: H <= 5 cm)
    ls.DIRECTION_DEG: 0.0,         # epsilon of Eq. 2-3, 0 = forward (+x)
    # Bus.
    ls.SERVOS: hexapod.SERVOS,
    ls.FIRST_ID: 1,
    ls.RETURN_DELAY_US: 0,         # written to every servo at configure time
    ls.BAUD: 1000000,
    ls.PROTOCOL: 1,                # 1: AX-12 (Protocol 1.0); 2: X series, one SYNC_READ a cycle
}


def merged(overrides):
    """DEFAULTS updated with ``overrides`` (unknown keys are an error, not ignored)."""
    out = dict(DEFAULTS)
    if overrides:
        for k in overrides:
            if k not in out:
                raise ValueError("unknown firmware config key %r" % k)
            out[k] = overrides[k]
    return out
