# protocol/can_frames.py under the real micropython binary (checks.py asserts, no pytest).
# Prints one "frame <name> <hex>" line per fixed case so the pytest side can compare the
# bytes with CPython's and cantools', then "OK can_frames <checks>".
from protocol import can_frames as cf
from tests.micropython.checks import check, done, raises

CASES = (
    ("actuator_command", {"fx_n": 1.9999, "tau1_nm": -0.1, "tau2_nm": 0.05}),
    ("body_pose", {"x_m": -0.123456, "roll_rad": 0.7854, "pitch_rad": -0.3}),
    ("body_rate", {"vx_m_s": 0.05, "roll_rate_rad_s": -3.5, "pitch_rate_rad_s": 12.25}),
    ("force", {"fx_n": -1.5, "fy_n": 0.0042, "fz_n": 2.0, "sample": 65535}),
    ("beam_estimate", {"k1_nm_per_rad": 0.25, "k2_nm_per_rad": 0.27, "hb_m": 0.0,
                       "mode": cf.MODE_ROLL}),
    ("tactile", {"switches": 0x21, "overcoming": 0x04, "step_counter": 123456789}),
    ("gait_command", {"command": cf.COMMAND_START, "gait": cf.GAIT_TRIPOD,
                      "step_length_m": 0.06, "step_height_m": 0.03, "period_s": 1.2}),
    ("heartbeat", {"state": cf.STATE_SAFE_STOP,
                   "fault_flags": cf.FAULT_SERVO_LOST | cf.FAULT_VOLTAGE,
                   "cycle": 4000000000, "overruns": 7}),
    # saturation and wrap-around
    ("actuator_command", {"fx_n": 100.0, "tau1_nm": -100.0, "tau2_nm": 0.0}),
    ("force", {"fx_n": 0.0, "fy_n": 0.0, "fz_n": 0.0, "sample": 65536 + 3}),
)

for name, values in CASES:
    arb_id, data = cf.encode(name, **values)
    check(len(data) == cf.DLC[name], (name, "dlc"))
    got_name, out = cf.decode(arb_id, data)
    check(got_name == name, (name, got_name))
    for sig in cf.FRAMES[name][2]:
        sname, kind, scale = sig[0], sig[1], sig[2]
        if kind == cf.SCALED:
            lo, hi = sig[3] * scale, sig[4] * scale
            want = min(max(values[sname], lo), hi)
            check(abs(out[sname] - want) <= scale / 2 + 1e-12, (name, sname, out[sname], want))
        elif kind == cf.COUNTER:
            check(out[sname] == values[sname] & sig[4], (name, sname))
        else:
            check(out[sname] == values[sname], (name, sname))
    print("frame", name, "%03x" % arb_id, "".join("%02x" % b for b in data))

for bad in (lambda: cf.encode("heartbeat", state=9, fault_flags=0, cycle=0, overruns=0),
            lambda: cf.decode(0x7FF, bytes(8)),
            lambda: cf.decode(cf.ID_FORCE, bytes(3)),
            lambda: cf.encode("force", fx_n=0.0)):
    raises(bad, ValueError, "no ValueError")

check(cf.legs_set(0x21) == ["LF", "RH"], "legs_set")
check(cf.faults_set(0x11) == ["servo_lost", "voltage"], "faults_set")
done("can_frames")
