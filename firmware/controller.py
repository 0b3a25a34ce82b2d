"""The fixed-rate hexapod control loop (seed 003 Sec. 2.4 and 3.1), MicroPython-compatible.

Each cycle: sample and debounce the six limit switches, take CAN commands, advance the
gait clock, latch each leg's step parameters at lift-off (Eq. 5-7), foot targets from
Eq. 2-4, IK, one SYNC_WRITE of all 18 goals, a few status reads, fault checks, telemetry
(heartbeat and tactile frames at 10 Hz and on every change), then sleep to the next slot.
An overrun is counted and the loop skips to the next free slot. A servo silent for
``servo_lost_s`` or repeating a shutdown error brings the robot to its neutral stance and
a stop with a stated reason; the loop keeps running (telemetry, reads) until told to end.
"""
import json
import math

from firmware import servo_bus as master_mod
from firmware import gait as gait_mod
from firmware import tactile
from firmware import trajectory as traj
from protocol import sim_link
from protocol import ax12
from protocol import can_frames as cf
from protocol import hexapod
from protocol import dynamixel as dxl

SAFE_SPEED_RAD_S = 1.0      # joint speed limit while going to the safe stance
SPEED_MARGIN = 1.5          # moving-speed limit = margin x the speed the targets need
COMPLIANCE_MARGIN = 1       # AX-12 units, e-manual default
COMPLIANCE_SLOPE = 32


class Controller:
    def __init__(self, board, cfg):
        self.board = board
        self.cfg = cfg
        n = cfg["servos"]
        if n != 18:
            raise ValueError("the hexapod needs 18 servos, config says %d" % n)
        first = cfg["first_id"]
        self.ids = [first + k for k in range(18)]
        self.legs = [hexapod.Leg(i) for i in range(6)]
        self.neutral = [hexapod.neutral_foot(i) for i in range(6)]
        self.master = master_mod.Master(board.uart, self.ids, cfg["baud"],
                                        retries=cfg["read_retries"])
        self.gait = gait_mod.Gait(cfg["gait"], cfg["period_s"])
        self.period_us = int(1000000 / cfg["cycle_hz"])
        samples = int(cfg["debounce_ms"] * 1000 // self.period_us) or 1
        self.switches = tactile.Switches(samples)
        self.rule = tactile.ObstacleRule(cfg["step_length_m"], cfg["step_height_m"],
                                         cfg["max_obstacle_height_m"], cfg["tactile"])
        self.eps = math.radians(cfg["direction_deg"])
        self.ce = math.cos(self.eps)
        self.se = math.sin(self.eps)
        self.lost_us = int(cfg["servo_lost_s"] * 1000000)
        self.critical_errors = cfg["critical_errors"]
        self.reads_per_cycle = cfg["reads_per_cycle"]
        self.telemetry_us = int(1000000 / cfg["telemetry_hz"])
        self.state = cf.STATE_BOOT
        self.commanded_m = 0.0
        self.stop_reason = None
        self.cycle = 0
        self.overruns = 0
        self.now_us = 0            # monotonic virtual time since boot
        self.boot_us = 0           # scan and configuration took this long
        self._tick = board.ticks_us()
        self.next_telemetry_us = 0
        self.positions = [512] * 18
        self.speeds = [0] * 18
        self.goal_rad = [0.0] * 18
        self.limits = [(0, 1023)] * 18
        self.swinging = 0          # bit i: leg i is in its transfer phase
        self.cursor = 0            # rotating status-read position
        self.suspect = []          # servo indices whose last read failed
        self.found = []
        self.window_flags = 0      # fault flags seen since the last heartbeat
        self.commands = 0
        self.compute_us = 0
        self.compute_max_us = 0
        self.compute_cycles = 0
        for j in range(18):
            leg = self.legs[j // 3]
            lo, hi = leg.servo_limits_rad(j % 3)
            self.limits[j] = (ax12.rad_to_position(lo), ax12.rad_to_position(hi))

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
        for j in range(18):
            lo, hi = self.limits[j]
            if not self.master.configure_eeprom(self.ids[j], lo, hi, board):
                return self._not_configured(self.ids[j])
        board.sleep_until(board.ticks_add(board.ticks_us(), master_mod.EEPROM_SETTLE_US))
        for j in range(18):
            if not self.master.configure_ram(self.ids[j], COMPLIANCE_MARGIN, COMPLIANCE_SLOPE,
                                             board):
                return self._not_configured(self.ids[j])
        self.master.return_delay_us = 2 * (self.cfg["return_delay_us"] // 2)
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

    # --- the loop ---------------------------------------------------------------------
    def run(self):
        board = self.board
        t_next = board.ticks_us()
        while not board.ended:
            p0 = board.perf_us()
            io0 = board.io_us()
            self.step()
            dt = board.perf_us() - p0 - (board.io_us() - io0)
            self.compute_us += dt
            self.compute_cycles += 1
            if dt > self.compute_max_us:
                self.compute_max_us = dt
            t_next = board.ticks_add(t_next, self.period_us)
            late = board.ticks_diff(board.ticks_us(), t_next)
            if late > 0:
                self.overruns += 1
                self.window_flags |= cf.FAULT_OVERRUN
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
                    self.board.event(sim_link.EVENT_TACTILE, json.dumps(
                        {"leg": hexapod.LEGS[i], "switch": 1 if pressed & (1 << i) else 0}))
        while self.board.can.any():
            self._command(self.board.can.recv(), now)
        if self.state == cf.STATE_WALKING:
            report = self._walk_targets(now, pressed) or report
            g = self.gait
            # Dead reckoning at the nominal body speed: what the gait commands, not where
            # the body went (the host compares the two).
            self.commanded_m += hexapod.speed_m_s(g.name, self.rule.l_i,
                                                  g.period_us * 1e-6) * self.period_us * 1e-6
        else:
            self._safe_targets()
        self.master.sync_write(self.positions, self.speeds, self.board)
        self._read_status()
        self._check_faults()
        if report:
            self._tactile_frame()
        if self.now_us >= self.next_telemetry_us:
            self.next_telemetry_us = self.now_us + self.telemetry_us
            self._heartbeat()
            if not report:
                self._tactile_frame()

    def _walk_targets(self, now, pressed):
        g = self.gait
        g.advance(now)
        t = g.t
        T = g.T
        rule = self.rule
        changed = False
        for i in range(6):
            phi = g.phases[i]
            bit = 1 << i
            swing = phi < t <= phi + 1
            if swing and not (self.swinging & bit):
                if rule.lift_off(i, pressed & bit):
                    changed = True
                    self.board.event(sim_link.EVENT_TACTILE, json.dumps(
                        {"leg": hexapod.LEGS[i], "overcoming": 1 if rule.overcoming & bit else 0,
                         "step_length_m": rule.l[i], "step_height_m": rule.h[i]}))
            if swing:
                self.swinging |= bit
            else:
                self.swinging &= ~bit
            s = traj.stroke(t, rule.l[i], T, phi) - rule.l_i / 2
            z = traj.lift(t, rule.h[i], phi)
            nx, ny, nz = self.neutral[i]
            self._leg_goal(i, nx + self.ce * s, ny + self.se * s, nz + z, 0.0)
        return changed

    def _safe_targets(self):
        for i in range(6):
            nx, ny, nz = self.neutral[i]
            self._leg_goal(i, nx, ny, nz, SAFE_SPEED_RAD_S)

    def _leg_goal(self, i, x, y, z, speed_rad_s):
        leg = self.legs[i]
        q = leg.ik(x, y, z)
        dt_s = self.period_us * 1e-6
        for j in range(3):
            k = 3 * i + j
            rad = leg.servo_rad(j, q[j])
            lo, hi = self.limits[k]
            pos = ax12.rad_to_position(rad)
            pos = lo if pos < lo else (hi if pos > hi else pos)
            if speed_rad_s > 0:
                spd = speed_rad_s
            else:
                spd = SPEED_MARGIN * abs(rad - self.goal_rad[k]) / dt_s
            self.goal_rad[k] = rad
            self.positions[k] = pos
            self.speeds[k] = ax12.rad_s_to_speed(spd)

    def _read_status(self):
        """Poll servos whose last read failed first, then the rotating subset."""
        m = self.master
        budget = self.reads_per_cycle
        retry = self.suspect
        self.suspect = []
        for k in retry[:budget]:
            if not m.read_present(self.ids[k], self.board):
                self.suspect.append(k)
        self.suspect.extend(retry[budget:])
        budget -= min(len(retry), budget)
        while budget > 0:
            k = self.cursor
            self.cursor = (k + 1) % 18
            budget -= 1
            if k in self.suspect:
                continue
            if not m.read_present(self.ids[k], self.board):
                self.suspect.append(k)

    def _check_faults(self):
        now = self._clock()
        flags = 0
        m = self.master
        for k in range(18):
            s = m.servos[self.ids[k]]
            silent = now - s.last_ok_us
            if k in self.suspect:
                flags |= cf.FAULT_SERVO_LOST
            if s.error_bits:
                flags |= cf.FAULT_SERVO_ERROR
                if s.error_bits & dxl.ERR_INPUT_VOLTAGE:
                    flags |= cf.FAULT_VOLTAGE
                if s.error_bits & dxl.ERR_OVERHEATING:
                    flags |= cf.FAULT_OVERHEAT
            if self.state in (cf.STATE_WALKING, cf.STATE_STOPPED):
                if silent > self.lost_us:
                    self._stop(cf.STATE_SAFE_STOP, "servo %d (%s %s) lost: no valid status for %.1f s"
                               % (s.id, hexapod.LEGS[k // 3], hexapod.JOINTS[k % 3], silent * 1e-6))
                elif s.critical_run >= self.critical_errors:
                    self._stop(cf.STATE_SAFE_STOP, "servo %d (%s %s) critical error: %s"
                               % (s.id, hexapod.LEGS[k // 3], hexapod.JOINTS[k % 3],
                                  "+".join(dxl.error_names(s.error_bits & master_mod.CRITICAL_BITS))))
        t, c, _ = m.counters()
        if t or c:
            flags |= cf.FAULT_BUS_ERROR
        self.window_flags |= flags

    # --- CAN --------------------------------------------------------------------------
    def _command(self, frame, now):
        arb_id, data = frame
        try:
            name, sig = cf.decode(arb_id, data)
        except ValueError:
            return
        if name != "gait_command":
            return
        self.commands += 1
        if sig["period_s"] > 0:
            self.gait.request(cf.GAIT_NAMES[sig["gait"]], sig["period_s"])
        if sig["step_length_m"] > 0 and sig["step_height_m"] > 0:
            self.rule.set_initial(sig["step_length_m"], sig["step_height_m"],
                                  self.cfg["max_obstacle_height_m"])
        if sig["command"] == cf.COMMAND_STOP and self.state == cf.STATE_WALKING:
            self.state = cf.STATE_STOPPED
        elif sig["command"] == cf.COMMAND_START and self.state == cf.STATE_STOPPED:
            self.state = cf.STATE_WALKING
            self.gait.restart(now)
            self.swinging = 0

    def _heartbeat(self):
        arb_id, data = cf.encode("heartbeat", state=self.state, fault_flags=self.window_flags,
                                 cycle=self.cycle, overruns=self.overruns)
        self.board.can.send(data, arb_id)
        self.window_flags = 0

    def _tactile_frame(self):
        arb_id, data = cf.encode("tactile", switches=self.switches.state,
                                 overcoming=self.rule.overcoming, step_counter=self.rule.steps)
        self.board.can.send(data, arb_id)

    # --- summary ----------------------------------------------------------------------
    def stats(self):
        m = self.master
        t, c, e = m.counters()
        servos = {}
        for s in m.servos.values():
            if s.timeouts or s.corrupt or s.errors:
                servos[str(s.id)] = {"timeouts": s.timeouts, "corrupt": s.corrupt,
                                     "errors": s.errors,
                                     "error_bits": dxl.error_names(s.error_bits)}
        clamped = 0
        for leg in self.legs:
            clamped += leg.clamped
        return {
            "state": cf.STATE_NAMES[self.state],
            "stop_reason": self.stop_reason,
            "gait": self.gait.name,
            "period_s": self.gait.period_us * 1e-6,
            "cycles": self.cycle,
            "overruns": self.overruns,
            "found": len(self.found),
            "boot_s": self.boot_us * 1e-6,
            "echo": bool(m.echo),
            "transactions": m.transactions,
            "sync_writes": m.sync_writes,
            "timeouts": t,
            "corrupt_replies": c,
            "error_statuses": e,
            "echo_mismatch": m.echo_mismatch,
            "servos": servos,
            "ik_clamped": clamped,
            "switch_edges": self.switches.edges,
            "trajectory_changes": self.rule.changes,
            "steps": self.rule.steps,
            "commanded_distance_m": self.commanded_m,
            "commands": self.commands,
            "compute_us_mean": (self.compute_us / self.compute_cycles) if self.compute_cycles else 0,
            "compute_us_max": self.compute_max_us,
        }
