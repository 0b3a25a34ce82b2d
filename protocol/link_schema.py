"""The JSON inside simulator-link messages, defined once: the hello's config (host ->
client) and the events' objects (client -> host). docs/link.md renders these tables.

Each table is ``(key, type, unit, meaning)``; type is one of protocol/schema.py ``KINDS``' names, unit ""
when the value has none. The key constants are what firmware/ and hil/ write and read
instead of their own string literals. MicroPython-compatible.
"""
from protocol import schema

# hello config: overrides of firmware/config.py DEFAULTS (any subset; unknown keys refused)
CYCLE_HZ = "cycle_hz"
READS_PER_CYCLE = "reads_per_cycle"
READ_RETRIES = "read_retries"
SERVO_LOST_S = "servo_lost_s"
CRITICAL_ERRORS = "critical_errors"
DEBOUNCE_MS = "debounce_ms"
TELEMETRY_HZ = "telemetry_hz"
TACTILE_ON = "tactile"
AUTOSTART = "autostart"
GAIT = "gait"
STEP_LENGTH_M = "step_length_m"
STEP_HEIGHT_M = "step_height_m"
PERIOD_S = "period_s"
MAX_OBSTACLE_HEIGHT_M = "max_obstacle_height_m"
DIRECTION_DEG = "direction_deg"
SERVOS = "servos"
FIRST_ID = "first_id"
RETURN_DELAY_US = "return_delay_us"
BAUD = "baud"
PROTOCOL = "protocol"

CONFIG = (
    (CYCLE_HZ, "number", "Hz", "control loop rate"),
    (READS_PER_CYCLE, "int", "", "servos polled for position/speed/load per cycle"),
    (READ_RETRIES, "int", "", "retries of a status read that timed out or was corrupt"),
    (SERVO_LOST_S, "number", "s", "no valid reply for this long -> safe stop"),
    (CRITICAL_ERRORS, "int", "", "consecutive overload/overheat statuses -> safe stop"),
    (DEBOUNCE_MS, "int", "ms", "a switch level must hold this long to count"),
    (TELEMETRY_HZ, "number", "Hz", "heartbeat and periodic tactile frame rate"),
    (TACTILE_ON, "bool", "", "Eq. 5-7 obstacle rule on"),
    (AUTOSTART, "bool", "", "walk after boot without a CAN start command"),
    (GAIT, "str", "", "gait name (protocol/hexapod.py GAITS)"),
    (STEP_LENGTH_M, "number", "m", "step length l_i"),
    (STEP_HEIGHT_M, "number", "m", "step height h_i"),
    (PERIOD_S, "number", "s", "gait period"),
    (MAX_OBSTACLE_HEIGHT_M, "number", "m", "H of Eq. 7"),
    (DIRECTION_DEG, "number", "deg", "walking direction epsilon, 0 = +x"),
    (SERVOS, "int", "", "servo count"),
    (FIRST_ID, "int", "", "ID of the first servo"),
    (RETURN_DELAY_US, "int", "us", "return delay written to every servo"),
    (BAUD, "int", "bit/s", "servo line rate"),
    (PROTOCOL, "int", "", "Dynamixel protocol: 1 (AX-12) or 2 (X series)"),
)

# EVENT_STATS: the firmware's counters when the run ends (firmware/telemetry.py stats)
STATE = "state"
STOP_REASON = "stop_reason"
CYCLES = "cycles"
OVERRUNS = "overruns"
FOUND = "found"
BOOT_S = "boot_s"
ECHO = "echo"
TRANSACTIONS = "transactions"
SYNC_WRITES = "sync_writes"
TIMEOUTS = "timeouts"
CORRUPT_REPLIES = "corrupt_replies"
ERROR_STATUSES = "error_statuses"
ECHO_MISMATCH = "echo_mismatch"
SERVO_ERRORS = "servos"
IK_CLAMPED = "ik_clamped"
SWITCH_EDGES = "switch_edges"
TRAJECTORY_CHANGES = "trajectory_changes"
STEPS = "steps"
COMMANDED_DISTANCE_M = "commanded_distance_m"
COMMANDS = "commands"
COMPUTE_US_MEAN = "compute_us_mean"
COMPUTE_US_MAX = "compute_us_max"

STATS = (
    (STATE, "str", "", "controller state (protocol/can_frames.py STATE_NAMES)"),
    (STOP_REASON, "str|null", "", "why it stopped, null while running"),
    (GAIT, "str", "", "gait at the end"),
    (PERIOD_S, "number", "s", "gait period at the end"),
    (CYCLES, "int", "", "control cycles run"),
    (OVERRUNS, "int", "", "cycles that ran past their period"),
    (FOUND, "int", "", "servos that answered the boot scan"),
    (BOOT_S, "number", "s", "virtual time the boot took"),
    (ECHO, "bool", "", "the line echoes the master's bytes"),
    (TRANSACTIONS, "int", "", "bus transactions (request + status)"),
    (SYNC_WRITES, "int", "", "SYNC_WRITE packets sent"),
    (TIMEOUTS, "int", "", "status reads that timed out"),
    (CORRUPT_REPLIES, "int", "", "status replies that failed to parse"),
    (ERROR_STATUSES, "int", "", "statuses with an error bit set"),
    (ECHO_MISMATCH, "int", "", "echoes that differed from what was sent"),
    (SERVO_ERRORS, "object", "", "servo ID -> {timeouts, corrupt, errors, error_bits}, "
     "only servos with a problem"),
    (IK_CLAMPED, "int", "", "goals the inverse kinematics clamped"),
    (SWITCH_EDGES, "int", "", "debounced switch edges"),
    (TRAJECTORY_CHANGES, "int", "", "Eq. 5-7 trajectory changes"),
    (STEPS, "int", "", "steps taken"),
    (COMMANDED_DISTANCE_M, "number", "m", "distance the gait commanded"),
    (COMMANDS, "int", "", "CAN commands taken"),
    (COMPUTE_US_MEAN, "number", "us", "wall time of a cycle's own work, mean (profiling)"),
    (COMPUTE_US_MAX, "int", "us", "the same, largest"),
)

# EVENT_TACTILE: a switch edge {leg, switch} or a lift-off {leg, overcoming, step_*}
LEG = "leg"
SWITCH = "switch"
OVERCOMING = "overcoming"
T_S = "t_s"   # added by the host when it receives the event

TACTILE = (
    (LEG, "str", "", "leg name (protocol/hexapod.py LEGS)"),
    (SWITCH, "int", "", "switch edge: 1 pressed, 0 released"),
    (OVERCOMING, "int", "", "lift-off: 1 if the leg is overcoming an obstacle"),
    (STEP_LENGTH_M, "number", "m", "lift-off: the leg's new l_i"),
    (STEP_HEIGHT_M, "number", "m", "lift-off: the leg's new h_i"),
)

# EVENT_FAULT: a fault the client detected
NAME = "name"
DETAIL = "detail"

FAULT = (
    (NAME, "str", "", "fault name"),
    (DETAIL, "str", "", "free text"),
)

def problems(obj, table, required=False):
    """What is wrong with ``obj`` against ``table``: unknown keys, wrong types, and with
    ``required`` missing keys; an empty list when nothing is (protocol/schema.py checks)."""
    if not isinstance(obj, dict):
        return ["not a JSON object"]
    fields = {}
    for key, kind, _, _ in table:
        fields[key] = (kind, required)
    out = []
    for key, what in schema.problems(obj, fields):
        if what == schema.UNKNOWN:
            out.append("unknown key %r" % key)
        elif what == schema.MISSING:
            out.append("missing key %r" % key)
        else:
            out.append("%s should be %s, not %r" % (key, what, obj[key]))
    return out
