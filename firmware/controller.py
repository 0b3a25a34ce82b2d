"""The fixed-rate hexapod control loop (seed 003 Sec. 2.4 and 3.1), MicroPython-compatible.

Each cycle: sample and debounce the six limit switches, take CAN commands, advance the
gait clock, latch each leg's step parameters at lift-off (Eq. 5-7), foot targets from
Eq. 2-4, IK, one SYNC_WRITE of all 18 goals, a few status reads, fault checks, telemetry
(heartbeat and tactile frames at 10 Hz and on every change), then sleep to the next slot.
An overrun is counted and the loop skips to the next free slot. A servo silent for
``servo_lost_s`` or repeating a shutdown error brings the robot to its neutral stance and
a stop with a stated reason; the loop keeps running (telemetry, reads) until told to end.

The controller owns the robot's state and the loop; its parts: ``servo_goals`` (IK to
servo goals), ``fault_policy`` (status reads, when to stop), ``commands`` (CAN gait
commands), ``telemetry`` (frames, events, the run summary).
"""
import math

from firmware.servo_bus import master_class
from firmware.servo_bus.v1 import EEPROM_SETTLE_US
from firmware import tactile
from firmware import trajectory as traj
from firmware.commands import GaitCommands
from firmware.fault_policy import FaultPolicy
from firmware.gait import Gait
from firmware.servo_goals import ServoGoals
from firmware.telemetry import Telemetry
from protocol import can_frames as cf
from protocol import hexapod
from protocol import link_schema as ls
from protocol import sim_link

SAFE_SPEED_RAD_S = 1.0      # joint speed limit while going to the safe stance
COMPLIANCE_MARGIN = 1       # AX-12 units, e-manual default
COMPLIANCE_SLOPE = 32


class Controller:
    """The robot's state machine (boot, walking, stopped, safe stop, fault) and its loop."""

    def __init__(self, board, cfg):
        self.board = board
        self.cfg = cfg
        n = cfg["servos"]
        if n != hexapod.SERVOS:
            raise ValueError("the hexapod needs 18 servos, config says %d" % n)
        first = cfg["first_id"]
        self.ids = [first + k for k in range(18)]
        master = master_class(cfg[ls.PROTOCOL])
        self.master = master(board.uart, self.ids, cfg["baud"], retries=cfg["read_retries"])
        self.gait = Gait(cfg["gait"], cfg["period_s"])
        self.period_us = int(1000000 / cfg["cycle_hz"])
        self.goals = ServoGoals(self.period_us)
        samples = int(cfg["debounce_ms"] * 1000 // self.period_us) or 1
        self.switches = tactile.Switches(samples)
        self.rule = tactile.ObstacleRule(cfg["step_length_m"], cfg["step_height_m"],
                                         cfg["max_obstacle_height_m"], cfg["tactile"])
        self.set_direction(math.radians(cfg["direction_deg"]))
        # each leg strokes along the direction it took at its last lift-off (Eq. 2-3's
        # epsilon), so a new heading never moves a foot that is on the ground
        self.leg_dir = [(self.ce, self.se)] * 6
        self.faults = FaultPolicy(self.ids, cfg)
        self.commands = GaitCommands(cfg["max_obstacle_height_m"])
        self.telemetry = Telemetry(board, cfg["telemetry_hz"])
        self.state = cf.STATE_BOOT
        self.commanded_m = 0.0
        self.stop_reason = None
        self.cycle = 0
        self.overruns = 0
        self.now_us = 0            # monotonic virtual time since boot
        self.boot_us = 0           # scan and configuration took this long
        self._tick = board.ticks_us()
        self.swinging = 0          # bit i: leg i is in its transfer phase
        self.found = []

    # --- time -------------------------------------------------------------------------
    def _clock(self):
        t = self.board.ticks_us()
        self.now_us += self.board.ticks_diff(t, self._tick)
        self._tick = t
        return self.now_us

    # --- boot -------------------------------------------------------------------------
    def boot(self):
        """Scan for the 18 servos and configure them; False (with a reason) if any is missing."""
        self.state = cf.STATE_SCANNING
        self._heartbeat()
        self.found = self.master.scan(self.board)
        missing = [i for i in self.ids if i not in self.found]
        if missing:
            self._stop(cf.STATE_FAULT, "scan found %d of 18 servos (missing id %s)"
                       % (len(self.found), ", ".join(str(i) for i in missing)))
            return False
        # EEPROM for all servos, one wait after the last of those writes, then RAM: a servo
        # that has just written its EEPROM ignores packets for a few ms
        board = self.board
        self.master.delay_set_us = 2 * (self.cfg["return_delay_us"] // 2)
        for j in range(18):
            lo, hi = self.goals.limits[j]
            if not self.master.configure_eeprom(self.ids[j], lo, hi, board):
                return self._not_configured(self.ids[j])
        board.sleep_until(board.ticks_add(board.ticks_us(), EEPROM_SETTLE_US))
        for j in range(18):
            if not self.master.configure_ram(self.ids[j], COMPLIANCE_MARGIN, COMPLIANCE_SLOPE,
                                             board):
                return self._not_configured(self.ids[j])
        self.master.return_delay_us = self.master.delay_set_us
        now = self.boot_us = self._clock()
        for s in self.master.servos.values():
            s.last_ok_us = now
        self.state = cf.STATE_WALKING if self.cfg["autostart"] else cf.STATE_STOPPED
        self.gait.restart(now)
        return True

    def _not_configured(self, dev_id):
        self._stop(cf.STATE_FAULT, "servo %d did not acknowledge its configuration" % dev_id)
        return False

    def _stop(self, state, reason):
        if self.stop_reason is None:
            self.stop_reason = reason
            self.board.event(sim_link.EVENT_STOP, reason)
        self.state = state

    def stop_walking(self):
        """Walking -> stopped (in place); any other state is kept."""
        if self.state == cf.STATE_WALKING:
            self.state = cf.STATE_STOPPED

    def set_direction(self, eps_rad):
        """The walking direction epsilon (rad, from the body's x axis), for the next lift-offs."""
        self.ce = math.cos(eps_rad)
        self.se = math.sin(eps_rad)

    def start_walking(self, now_us):
        """Stopped -> walking, the gait restarting at ``now_us``; any other state is kept."""
        if self.state == cf.STATE_STOPPED:
            self.state = cf.STATE_WALKING
            self.gait.restart(now_us)
            self.swinging = 0

    # --- the loop ---------------------------------------------------------------------
    def run(self):
        board = self.board
        telemetry = self.telemetry
        t_next = board.ticks_us()
        while not board.ended:
            p0 = board.perf_us()
            io0 = board.io_us()
            self.step()
            telemetry.compute(board.perf_us() - p0 - (board.io_us() - io0))
            t_next = board.ticks_add(t_next, self.period_us)
            late = board.ticks_diff(board.ticks_us(), t_next)
            if late > 0:
                self.overruns += 1
                telemetry.window_flags |= cf.FAULT_OVERRUN
                t_next = board.ticks_add(t_next, (late // self.period_us + 1) * self.period_us)
            board.sleep_until(t_next)

    def step(self):
        """One control cycle."""
        now = self._clock()
        self.cycle += 1
        raw = 0
        sw = self.board.switches
        for i in range(6):
            if sw[i].value():
                raw |= 1 << i
        changed = self.switches.update(raw)
        pressed = self.switches.state
        self.rule.touched(pressed)
        report = changed != 0
        if changed:
            for i in range(6):
                if changed & (1 << i):
                    self.telemetry.switch_event(i, pressed & (1 << i))
        self.commands.take(self, now)
        if self.state == cf.STATE_WALKING:
            report = self._walk_targets(now, pressed) or report
            g = self.gait
            # Dead reckoning at the nominal body speed: what the gait commands, not where
            # the body went (the host compares the two).
            self.commanded_m += hexapod.speed_m_s(g.name, self.rule.l_i,
                                                  g.period_us * 1e-6) * self.period_us * 1e-6
        else:
            self._safe_targets()
        self.master.sync_write(self.goals.positions, self.goals.speeds, self.board)
        self.faults.read_status(self.master, self.board)
        self._check_faults()
        if report:
            self._tactile_frame()
        if self.telemetry.due(self.now_us):
            self._heartbeat()
            if not report:
                self._tactile_frame()

    def _walk_targets(self, now, pressed):
        g = self.gait
        g.advance(now)
        t = g.t
        T = g.T
        rule = self.rule
        goals = self.goals
        changed = False
        for i in range(6):
            phi = g.phases[i]
            bit = 1 << i
            swing = phi < t <= phi + 1
            if swing and not (self.swinging & bit):
                self.leg_dir[i] = (self.ce, self.se)
                if rule.lift_off(i, pressed & bit):
                    changed = True
                    self.telemetry.lift_off_event(i, rule)
            if swing:
                self.swinging |= bit
            else:
                self.swinging &= ~bit
            s = traj.stroke(t, rule.l[i], T, phi) - rule.l_i / 2
            z = traj.lift(t, rule.h[i], phi)
            nx, ny, nz = goals.neutral[i]
            ce, se = self.leg_dir[i]
            goals.set_leg(i, nx + ce * s, ny + se * s, nz + z, 0.0)
        return changed

    def _safe_targets(self):
        goals = self.goals
        for i in range(6):
            nx, ny, nz = goals.neutral[i]
            goals.set_leg(i, nx, ny, nz, SAFE_SPEED_RAD_S)

    def _check_faults(self):
        now = self._clock()
        armed = self.state in (cf.STATE_WALKING, cf.STATE_STOPPED)
        self.telemetry.window_flags |= self.faults.check(self.master, now, armed)
        if self.faults.reason is not None:
            self._stop(cf.STATE_SAFE_STOP, self.faults.reason)

    def _heartbeat(self):
        self.telemetry.heartbeat(self.state, self.cycle, self.overruns)

    def _tactile_frame(self):
        self.telemetry.tactile_frame(self.switches.state, self.rule)
