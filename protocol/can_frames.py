"""hexhil's CAN frames: pack and unpack in SI units (MicroPython-compatible).

``protocol/hexhil.dbc`` documents the same frames for CAN tools (cantools, SavvyCAN,
``cantools monitor``); a test proves the two agree bit for bit. Classic CAN, standard
11-bit IDs, little-endian signals. Lower ID wins arbitration, so the control loop's
frames have the lowest IDs and the heartbeat the highest.

Scaled signals saturate at the ends of their range (a controller's command must never
wrap round); counters wrap; enums and bitfields out of range raise ValueError.
"""
import struct

from protocol.hexapod import LEGS

# --- IDs (DBC ``BO_``) --------------------------------------------------------------
ID_ACTUATOR_COMMAND = 0x100
ID_BODY_POSE = 0x110
ID_BODY_RATE = 0x111
ID_FORCE = 0x120
ID_BEAM_ESTIMATE = 0x130
ID_TACTILE = 0x140
ID_LIMIT_SWITCHES = 0x150
ID_GAIT_COMMAND = 0x200
ID_HEADING_COMMAND = 0x201
ID_HEARTBEAT = 0x700

# --- Enum values (DBC ``VAL_``) -------------------------------------------------------
STATE_BOOT = 0
STATE_SCANNING = 1
STATE_WALKING = 2
STATE_STOPPED = 3
STATE_SAFE_STOP = 4
STATE_FAULT = 5
STATE_NAMES = ("boot", "scanning", "walking", "stopped", "safe_stop", "fault")

COMMAND_STOP = 0
COMMAND_START = 1
COMMAND_NAMES = ("stop", "start")

GAIT_TRIPOD = 0
GAIT_WAVE = 1
GAIT_NAMES = ("tripod", "wave")

MODE_UNKNOWN = 0
MODE_PITCH = 1   # seed 000: push the beams down, body pitched up
MODE_ROLL = 2    # seed 000: roll into the gap between the beams
MODE_NAMES = ("unknown", "pitch", "roll")

# heartbeat.fault_flags bits
FAULT_SERVO_LOST = 0x01   # a servo stopped answering
FAULT_SERVO_ERROR = 0x02  # a status packet carried error bits
FAULT_OVERRUN = 0x04      # a control cycle ran past its deadline
FAULT_BUS_ERROR = 0x08    # bad checksum / length / timeout on the Dynamixel bus
FAULT_VOLTAGE = 0x10      # input voltage out of the servos' limits
FAULT_OVERHEAT = 0x20     # a servo reported overheating
FAULT_NAMES = ("servo_lost", "servo_error", "overrun", "bus_error", "voltage", "overheat")

# tactile.switches / tactile.overcoming bits: bit i is leg LEGS[i] (protocol/hexapod.py)
LEG_BITS = 0x3F

# --- Frame table --------------------------------------------------------------------
# Signal kinds: scaled physical value (saturates), counter (wraps), enum and bitfield
# (out of range raises; a bitfield's unused high bits are ignored on decode).
SCALED = 0
COUNTER = 1
ENUM = 2
BITS = 3

# name -> (arb_id, struct format, ((signal, kind, scale, raw_min, raw_max), ...))
# Scales and ranges chosen from seed 000's magnitudes (Sec. II-I limits |F_x| <= 2 N,
# |tau| <= 0.1 N m; beam stiffness 0.01-0.78 N m/rad in Sec. III and IV).
FRAMES = {
    "actuator_command": (ID_ACTUATOR_COMMAND, "<hhh", (
        ("fx_n", SCALED, 0.0001, -32768, 32767),
        ("tau1_nm", SCALED, 0.00001, -32768, 32767),
        ("tau2_nm", SCALED, 0.00001, -32768, 32767),
    )),
    "body_pose": (ID_BODY_POSE, "<ihh", (
        ("x_m", SCALED, 0.000001, -2147483648, 2147483647),
        ("roll_rad", SCALED, 0.0001, -32768, 32767),
        ("pitch_rad", SCALED, 0.0001, -32768, 32767),
    )),
    "body_rate": (ID_BODY_RATE, "<hhh", (
        ("vx_m_s", SCALED, 0.0001, -32768, 32767),
        ("roll_rate_rad_s", SCALED, 0.001, -32768, 32767),
        ("pitch_rate_rad_s", SCALED, 0.001, -32768, 32767),
    )),
    "force": (ID_FORCE, "<hhhH", (
        ("fx_n", SCALED, 0.001, -32768, 32767),
        ("fy_n", SCALED, 0.001, -32768, 32767),
        ("fz_n", SCALED, 0.001, -32768, 32767),
        ("sample", COUNTER, 1, 0, 0xFFFF),
    )),
    "beam_estimate": (ID_BEAM_ESTIMATE, "<HHhB", (
        ("k1_nm_per_rad", SCALED, 0.00002, 0, 65535),
        ("k2_nm_per_rad", SCALED, 0.00002, 0, 65535),
        ("hb_m", SCALED, 0.00002, -32768, 32767),
        ("mode", ENUM, 1, 0, 2),
    )),
    "tactile": (ID_TACTILE, "<BBI", (
        ("switches", BITS, 1, 0, LEG_BITS),
        ("overcoming", BITS, 1, 0, LEG_BITS),
        ("step_counter", COUNTER, 1, 0, 0xFFFFFFFF),
    )),
    # The rig's ground truth of the six switches (hexhil bus --world --can-server).
    "limit_switches": (ID_LIMIT_SWITCHES, "<BB", (
        ("switches", BITS, 1, 0, LEG_BITS),
        ("sequence", COUNTER, 1, 0, 0xFF),
    )),
    "gait_command": (ID_GAIT_COMMAND, "<BBHHH", (
        ("command", ENUM, 1, 0, 1),
        ("gait", ENUM, 1, 0, 1),
        ("step_length_m", SCALED, 0.0001, 0, 65535),
        ("step_height_m", SCALED, 0.0001, 0, 65535),
        ("period_s", SCALED, 0.001, 0, 65535),
    )),
    # The walking direction relative to the body's x axis (crab walk; seed 003 Eq. 2-3's
    # epsilon); each leg takes it at its next lift-off.
    "heading_command": (ID_HEADING_COMMAND, "<h", (
        ("direction_rad", SCALED, 0.0001, -32768, 32767),
    )),
    "heartbeat": (ID_HEARTBEAT, "<BBIH", (
        ("state", ENUM, 1, 0, 5),
        ("fault_flags", BITS, 1, 0, 0x3F),
        ("cycle", COUNTER, 1, 0, 0xFFFFFFFF),
        ("overruns", COUNTER, 1, 0, 0xFFFF),
    )),
}

BY_ID = {}
for _name in FRAMES:
    BY_ID[FRAMES[_name][0]] = _name
# Data length of each frame in bytes (the DBC's DLC).
DLC = {}
for _name in FRAMES:
    DLC[_name] = struct.calcsize(FRAMES[_name][1])


def signals(name):
    """The signal names of frame ``name``, in wire order."""
    return tuple(s[0] for s in FRAMES[name][2])


def _raw(frame, sig, value):
    sname, kind, scale, lo, hi = sig
    if value - value != 0:  # NaN or infinity: no raw value stands for it
        raise ValueError("%s.%s = %r is not a finite number" % (frame, sname, value))
    if kind == SCALED:
        q = value / scale  # a huge finite value over a small scale is infinity: clamp first
        if q <= lo:
            return lo
        if q >= hi:
            return hi
        return int(round(q))
    raw = int(value)
    if kind == COUNTER:
        return raw & hi
    if raw < lo or raw > hi:
        raise ValueError("%s.%s = %d is out of range %d..%d" % (frame, sname, raw, lo, hi))
    return raw


def encode(name, **values):
    """Pack frame ``name`` from SI values; return ``(arb_id, data)``. Every signal is required."""
    try:
        arb_id, fmt, sigs = FRAMES[name]
    except KeyError:
        raise ValueError("unknown CAN frame %r" % name)
    raws = []
    for sig in sigs:
        try:
            v = values[sig[0]]
        except KeyError:
            raise ValueError("frame %s: missing signal %s" % (name, sig[0]))
        raws.append(_raw(name, sig, v))
    if len(values) != len(sigs):
        extra = [k for k in values if k not in signals(name)]
        raise ValueError("frame %s has no signal %s" % (name, ", ".join(extra)))
    return arb_id, struct.pack(fmt, *raws)


def decode(arb_id, data):
    """Unpack a frame; return ``(name, {signal: value})`` in SI units (ints for enums/counters).

    Raises ValueError for an ID that is not hexhil's or data shorter than the frame.
    An enum outside its choices is passed on as cantools does: check before indexing names.
    Bits the DBC leaves unused (the top two of a leg bitfield) are ignored, as cantools does.
    """
    name = BY_ID.get(arb_id)
    if name is None:
        raise ValueError("unknown CAN id 0x%03X" % arb_id)
    _, fmt, sigs = FRAMES[name]
    if len(data) < DLC[name]:
        raise ValueError("frame %s needs %d bytes, got %d" % (name, DLC[name], len(data)))
    raws = struct.unpack_from(fmt, data, 0)
    out = {}
    for i in range(len(sigs)):
        sname, kind, scale, lo, hi = sigs[i]
        raw = raws[i]
        if kind == SCALED:
            out[sname] = raw * scale
        elif kind == BITS:
            out[sname] = raw & hi
        else:
            out[sname] = raw
    return name, out


def legs_set(bits):
    """Names of the legs whose bit is set in a ``switches``/``overcoming`` bitfield."""
    return [LEGS[i] for i in range(6) if bits & (1 << i)]


def faults_set(flags):
    """Names of the faults set in ``heartbeat.fault_flags``."""
    return [FAULT_NAMES[i] for i in range(6) if flags & (1 << i)]
