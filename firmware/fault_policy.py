"""Which servos the loop reads each cycle, and when a servo's health stops the robot.

Seed 003 Sec. 2.4's loop on a shared half-duplex line: a few status reads per cycle, the
servos whose last read failed first, then a rotating subset. A servo with no valid status
for ``servo_lost_s`` (long enough to ride a 2 s unplug), or ``critical_errors`` overload or
overheat statuses in a row, is a reason to stop in the neutral stance. MicroPython-compatible.
"""
from firmware.servo_bus.v1 import CRITICAL_BITS
from protocol import can_frames as cf
from protocol.dynamixel import v1 as dxl
from protocol.hexapod import JOINTS, LEGS


class FaultPolicy:
    """Status-read schedule and the servo fault checks, over the 18 servos in ID order."""

    def __init__(self, ids, cfg):
        self.ids = ids
        self.lost_us = int(cfg["servo_lost_s"] * 1000000)
        self.critical_errors = cfg["critical_errors"]
        self.reads_per_cycle = cfg["reads_per_cycle"]
        self.cursor = 0            # rotating status-read position
        self.suspect = []          # servo indices whose last read failed
        self.reason = None         # why the last ``check`` wants a stop (None: no reason)

    def read_status(self, master, board):
        """This cycle's status reads, as the master's protocol does them (``read_cycle``:
        the rotating reads below, or one SYNC_READ of all 18 on an X-series bus)."""
        master.read_cycle(self, board)

    def read_rotating(self, master, board):
        """Poll servos whose last read failed first, then the rotating subset: the plan's
        reads, which a link of version 2 carries in one exchange (master.read_present_many)."""
        reads, first, rest = self.plan()
        ids = self.ids
        ok = master.read_present_many([(ids[k], skip) for k, skip in reads], board)
        suspect = [reads[j][0] for j in range(first) if not ok[j]]
        suspect.extend(rest)
        for j in range(first, len(reads)):
            if ok[j] is False:
                suspect.append(reads[j][0])
        self.suspect = suspect

    def plan(self):
        """The cycle's reads as (servo index, index of the earlier read whose failure skips
        this one, or -1), the count of those that retry a suspect, and the suspects left
        unread. A rotating read is skipped while its servo is suspect: carried over unread,
        or failed (or skipped) at its last read this cycle."""
        budget = self.reads_per_cycle
        retry = self.suspect
        reads = [(k, -1) for k in retry[:budget]]
        first = len(reads)
        rest = retry[budget:]
        budget -= first
        while budget > 0:
            k = self.cursor
            self.cursor = (k + 1) % 18
            budget -= 1
            if k in rest:
                continue
            skip = -1
            for j in range(len(reads)):
                if reads[j][0] == k:
                    skip = j
            reads.append((k, skip))
        return reads, first, rest

    def check(self, master, now_us, armed):
        """Heartbeat fault flags of the 18 servos and the bus at ``now_us``.

        With ``armed`` (walking or stopped), the first lost or critically failing servo sets
        ``reason``; otherwise ``reason`` is None.
        """
        flags = 0
        self.reason = None
        servos = master.servos
        ids = self.ids
        suspect = self.suspect
        lost_us = self.lost_us
        for k in range(18):
            s = servos[ids[k]]
            if k in suspect:
                flags |= cf.FAULT_SERVO_LOST
            if s.error_bits:
                flags |= cf.FAULT_SERVO_ERROR
                if s.error_bits & dxl.ERR_INPUT_VOLTAGE:
                    flags |= cf.FAULT_VOLTAGE
                if s.error_bits & dxl.ERR_OVERHEATING:
                    flags |= cf.FAULT_OVERHEAT
            if s.timeouts or s.corrupt:   # master.counters()'s, over the same 18 servos
                flags |= cf.FAULT_BUS_ERROR
            if armed:
                silent = now_us - s.last_ok_us
                if silent > lost_us:
                    self.reason = ("servo %d (%s %s) lost: no valid status for %.1f s"
                                   % (s.id, LEGS[k // 3], JOINTS[k % 3], silent * 1e-6))
                elif s.critical_run >= self.critical_errors:
                    self.reason = ("servo %d (%s %s) critical error: %s"
                                   % (s.id, LEGS[k // 3], JOINTS[k % 3],
                                      "+".join(dxl.error_names(s.error_bits & CRITICAL_BITS))))
                armed = self.reason is None
        return flags
