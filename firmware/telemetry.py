"""What the firmware tells the host: CAN heartbeat and tactile frames, link events, run stats.

Heartbeat (state, fault flags seen since the last one, cycle and overrun counts) and the
tactile frame go out at ``telemetry_hz``; the tactile frame also on every change. Switch
edges and trajectory changes are link events (JSON); at the end of a run ``stats`` is the
EVENT_STATS summary; the JSON keys are protocol/link_schema.py's. MicroPython-compatible.
"""
import json

from protocol import can_frames as cf
from protocol.dynamixel import v1 as dxl
from protocol import link_schema as ls
from protocol import sim_link
from protocol.hexapod import LEGS


class Telemetry:
    """The periodic frames' schedule, the fault flags of the current window, loop timing."""

    def __init__(self, board, telemetry_hz):
        self.board = board
        self.period_us = int(1000000 / telemetry_hz)
        self.next_us = 0
        self.window_flags = 0      # fault flags seen since the last heartbeat
        self.compute_us = 0        # wall time of the cycles' own work (profiling only)
        self.compute_max_us = 0
        self.compute_cycles = 0

    def due(self, now_us):
        """True once per ``telemetry_hz`` period (and schedules the next one)."""
        if now_us >= self.next_us:
            self.next_us = now_us + self.period_us
            return True
        return False

    def heartbeat(self, state, cycle, overruns):
        arb_id, data = cf.encode("heartbeat", state=state, fault_flags=self.window_flags,
                                 cycle=cycle, overruns=overruns)
        self.board.can.send(data, arb_id)
        self.window_flags = 0

    def tactile_frame(self, switches, rule):
        arb_id, data = cf.encode("tactile", switches=switches, overcoming=rule.overcoming,
                                 step_counter=rule.steps)
        self.board.can.send(data, arb_id)

    def switch_event(self, leg, pressed):
        self.board.event(sim_link.EVENT_TACTILE, json.dumps(
            {ls.LEG: LEGS[leg], ls.SWITCH: 1 if pressed else 0}))

    def lift_off_event(self, leg, rule):
        """Leg ``leg`` lifted off with new step parameters (Eq. 5-7)."""
        self.board.event(sim_link.EVENT_TACTILE, json.dumps(
            {ls.LEG: LEGS[leg], ls.OVERCOMING: 1 if rule.overcoming & (1 << leg) else 0,
             ls.STEP_LENGTH_M: rule.l[leg], ls.STEP_HEIGHT_M: rule.h[leg]}))

    def compute(self, dt_us):
        """Note one cycle's compute time (wall µs, host waits excluded)."""
        self.compute_us += dt_us
        self.compute_cycles += 1
        if dt_us > self.compute_max_us:
            self.compute_max_us = dt_us


def stats(ctl):
    """The run summary of controller ``ctl``, sent as EVENT_STATS when the run ends."""
    m = ctl.master
    t, c, e = m.counters()
    servos = {}
    for s in m.servos.values():
        if s.timeouts or s.corrupt or s.errors:
            servos[str(s.id)] = {"timeouts": s.timeouts, "corrupt": s.corrupt,
                                 "errors": s.errors,
                                 "error_bits": dxl.error_names(s.error_bits)}
    tel = ctl.telemetry
    return {
        ls.STATE: cf.STATE_NAMES[ctl.state],
        ls.STOP_REASON: ctl.stop_reason,
        ls.GAIT: ctl.gait.name,
        ls.PERIOD_S: ctl.gait.period_us * 1e-6,
        ls.CYCLES: ctl.cycle,
        ls.OVERRUNS: ctl.overruns,
        ls.FOUND: len(ctl.found),
        ls.BOOT_S: ctl.boot_us * 1e-6,
        ls.ECHO: bool(m.echo),
        ls.TRANSACTIONS: m.transactions,
        ls.SYNC_WRITES: m.sync_writes,
        ls.TIMEOUTS: t,
        ls.CORRUPT_REPLIES: c,
        ls.ERROR_STATUSES: e,
        ls.ECHO_MISMATCH: m.echo_mismatch,
        ls.SERVO_ERRORS: servos,
        ls.IK_CLAMPED: ctl.goals.clamped(),
        ls.SWITCH_EDGES: ctl.switches.edges,
        ls.TRAJECTORY_CHANGES: ctl.rule.changes,
        ls.STEPS: ctl.rule.steps,
        ls.COMMANDED_DISTANCE_M: ctl.commanded_m,
        ls.COMMANDS: ctl.commands.count,
        ls.COMPUTE_US_MEAN: (tel.compute_us / tel.compute_cycles) if tel.compute_cycles else 0,
        ls.COMPUTE_US_MAX: tel.compute_max_us,
    }
