"""X-series (XL430-W250-T) bus master in Protocol 2.0: scan, configure, one SYNC_WRITE of
profile velocity + goal position and ONE SYNC_READ of load, velocity and position for all
18 servos per cycle.

The same interface as v1.Master (the controller and the fault policy use either):
goals come in AX-12 units from firmware/servo_goals.py and are converted here, at the
bus, to XL430 pulses and velocity units; ``ServoStats`` keep the AX-12 meaning of their
error bits (the XL430's Hardware Error Status uses the same bit for input voltage,
overheating and overload). Packets are built with protocol/dynamixel/v2.py's ``build_into``
into preallocated buffers. MicroPython-compatible.
"""
from firmware.servo_bus.v1 import CORRUPT, OK, TIMEOUT, TIMEOUT_MARGIN_US, Master
from protocol.dynamixel import ax12
from protocol.dynamixel import v2 as dx2
from protocol.dynamixel import xl430 as xl

EEPROM_SETTLE_US = 10_000
STATUS_LEN = 11                 # FF FF FD 00 ID LEN LEN 55 ERR CRC CRC
PRESENT_ADDR = xl.PRESENT_LOAD  # load (2), velocity (4), position (4)
PRESENT_LEN = 10
SYNC_ADDR = xl.PROFILE_VELOCITY  # profile velocity (4) then goal position (4)
SYNC_LEN = 8
AX_TO_XL_SPEED = ax12.SPEED_RPM_PER_UNIT / xl.RPM_PER_UNIT


def ax_to_pulses(position):
    """An AX-12 position (0-1023 over 300 deg, centre 512) as XL430 pulses (centre 2048)."""
    return xl.rad_to_position(ax12.position_to_rad(position))


def pulses_to_ax(pulses):
    return ax12.rad_to_position(xl.position_to_rad(pulses))


class Master2(Master):
    """v1.Master's interface and counters (``scan``, ``counters``, ``read_present``,
    the retries and the unanswered send are inherited), its packets Protocol 2.0."""

    present_addr = PRESENT_ADDR
    present_len = PRESENT_LEN

    def __init__(self, uart, ids, baud=1000000, echo=None, retries=1):
        Master.__init__(self, uart, ids, baud, echo, retries)
        self.tx = bytearray(dx2.MAX_PACKET)
        self.rx = bytearray(2 * dx2.MAX_PACKET)
        self.params = bytearray(4 + len(ids) * (1 + SYNC_LEN))
        self.small = bytearray(12)
        self.parser = dx2.Parser()
        self.sync_reads = 0
        self._alerts = []

    # --- transactions ------------------------------------------------------------------
    def _exchange(self, n, nrx, replies):
        """Send ``tx[:n]``, receive up to ``nrx`` reply bytes; the index where they start
        (after our echo, if the line echoes) and how many bytes came."""
        echo_n = n if self.echo or self.echo is None else 0
        timeout = (echo_n + nrx) * self.byte_us + replies * self.return_delay_us \
            + TIMEOUT_MARGIN_US
        got = self.uart.transact(self.tx, n, self.rx, echo_n + nrx, timeout)
        self.transactions += 1
        if self.echo is None:
            self.echo = got >= n and self.rx[:n] == self.tx[:n]
        start = n if self.echo else 0
        if self.echo and got >= n and self.rx[:n] != self.tx[:n]:
            self.echo_mismatch += 1
        return start, got

    def _status(self, s, error, now):
        s.replies += 1
        s.present = True
        s.last_ok_us = now.ticks_us()
        if error:
            s.errors += 1
        if error & dx2.ALERT:
            self._alerts.append(s)   # read after the reply buffer has been parsed
        elif error & 0x7F == 0:
            s.critical_run = 0

    def _read_alerts(self, now):
        while self._alerts:
            self._hardware_error(self._alerts.pop(), now)

    def _hardware_error(self, s, now):
        """The alert bit: read Hardware Error Status, counted like the AX-12's error bits."""
        n = self._build_read(s.id, xl.HARDWARE_ERROR_STATUS, 1)
        start, got = self._exchange(n, STATUS_LEN + 1, 1)
        p = self.parser
        p.reset()
        for i in range(start, got):
            if p.push(self.rx[i]) and p.id == s.id and p.nparams == 2:
                bits = p.param(1)
                s.error_bits |= bits
                s.critical_run = s.critical_run + 1 if bits & (
                    xl.HW_OVERHEATING | xl.HW_OVERLOAD) else 0
                return

    def _transact(self, dev_id, n, nparams, now):
        """A transaction with one status packet of ``nparams`` (ERR included) expected."""
        start, got = self._exchange(n, STATUS_LEN - 1 + nparams, 1)
        s = self.servos.get(dev_id)
        p = self.parser
        p.reset()
        for i in range(start, got):
            if p.push(self.rx[i]) and p.id == dev_id and p.nparams == nparams:
                self.error = p.param(0)
                if s is not None:
                    self._status(s, self.error, now)
                    self._read_alerts(now)
                return OK
        if s is not None:
            if got > start:
                s.corrupt += 1
            else:
                s.timeouts += 1
        return CORRUPT if got > start else TIMEOUT

    def _build_read(self, dev_id, address, length):
        b = self.small
        b[0] = address & 0xFF
        b[1] = address >> 8
        b[2] = length
        b[3] = 0
        return dx2.build_into(self.tx, dev_id, dx2.READ, b, 4)

    # --- instructions -------------------------------------------------------------------
    def ping(self, dev_id, now):
        n = dx2.build_into(self.tx, dev_id, dx2.PING, b"", 0)
        return self._retry(dev_id, n, 4, now) == OK

    def write(self, dev_id, address, data, ndata, now):
        b = self.small
        b[0] = address & 0xFF
        b[1] = address >> 8
        for i in range(ndata):
            b[2 + i] = data[i]
        n = dx2.build_into(self.tx, dev_id, dx2.WRITE, b, ndata + 2)
        return self._retry(dev_id, n, 1, now) == OK and self.error & 0x7F == 0

    def read(self, dev_id, address, length, now):
        """READ; on success the data is at ``parser.buf[PARAMS_OFFSET + 1:]`` (after ERR)."""
        n = self._build_read(dev_id, address, length)
        return self._retry(dev_id, n, length + 1, now) == OK

    def _take_present(self, s):
        """Present load, velocity and position (after ERR) into ``s``: ``read_present``
        reads one servo, the loop all 18 at once with ``sync_read_present``."""
        p = self.parser
        s.load = p.param_u16(1)
        s.speed = p.param_u32(3)
        s.position = pulses_to_ax(p.param_u32(7))

    def configure_eeprom(self, dev_id, cw_limit, ccw_limit, now):
        """Return delay ``delay_set_us`` and the joint limits as Min/Max Position Limit (AX-12 units in):
        two EEPROM writes (the cells are apart), the servo deaf for a few ms after each."""
        if not self.write(dev_id, xl.RETURN_DELAY_TIME, bytes((self.delay_set_us // 2,)), 1,
                          now):
            return False
        now.sleep_until(now.ticks_add(now.ticks_us(), EEPROM_SETTLE_US))
        lim = bytearray(8)    # configuration only, not the loop
        hi = ax_to_pulses(ccw_limit)
        lo = ax_to_pulses(cw_limit)
        for k in range(4):
            lim[k] = (hi >> (8 * k)) & 0xFF
            lim[4 + k] = (lo >> (8 * k)) & 0xFF
        return self.write(dev_id, xl.MAX_POSITION_LIMIT, lim, 8, now)

    def configure_ram(self, dev_id, margin, slope, now):
        """Torque on (the AX-12's compliance has no XL430 counterpart: default gains)."""
        return self.write(dev_id, xl.TORQUE_ENABLE, b"\x01", 1, now)

    def sync_write(self, positions, speeds, now):
        """One SYNC_WRITE of profile velocity + goal position (AX-12 units in)."""
        prm = self.params
        prm[0] = SYNC_ADDR
        prm[1] = 0
        prm[2] = SYNC_LEN
        prm[3] = 0
        k = 4
        ids = self.ids
        for j in range(len(ids)):
            pos = ax_to_pulses(positions[j])
            spd = speeds[j]
            v = int(spd * AX_TO_XL_SPEED + 0.5) if spd else 0
            v = 1 if spd and v < 1 else v
            prm[k] = ids[j]
            prm[k + 1] = v & 0xFF
            prm[k + 2] = v >> 8
            prm[k + 3] = 0
            prm[k + 4] = 0
            prm[k + 5] = pos & 0xFF
            prm[k + 6] = (pos >> 8) & 0xFF
            prm[k + 7] = 0
            prm[k + 8] = 0
            k += 9
        n = dx2.build_into(self.tx, dx2.BROADCAST_ID, dx2.SYNC_WRITE, prm, k)
        self._send_unanswered(n)
        return n

    def read_cycle(self, policy, now):
        """A cycle's status reads: one SYNC_READ of all 18 (the failed ones are suspect)."""
        policy.suspect = self.sync_read_present(now)

    def sync_read_present(self, now):
        """ONE SYNC_READ of load, velocity and position of every servo; the servo indices
        that did not answer (a silent one ends the chain, so the rest are missing too)."""
        prm = self.params
        prm[0] = PRESENT_ADDR
        prm[1] = 0
        prm[2] = PRESENT_LEN
        prm[3] = 0
        ids = self.ids
        for j in range(len(ids)):
            prm[4 + j] = ids[j]
        n = dx2.build_into(self.tx, dx2.BROADCAST_ID, dx2.SYNC_READ, prm, 4 + len(ids))
        start, got = self._exchange(n, len(ids) * (STATUS_LEN + PRESENT_LEN), len(ids))
        self.sync_reads += 1
        p = self.parser
        p.reset()
        j = self._parse_present(start, got, 0, now)
        more = 0
        while j < len(ids) and p.pending() >= 7 and more < 4:
            # byte stuffing made a reply longer than planned: read the rest of it, and of
            # the replies after it, off the line (a receive without a transmit)
            left = (p.buf[5] | p.buf[6] << 8) + 7 - p.pending() + \
                (len(ids) - j - 1) * (STATUS_LEN + PRESENT_LEN)
            got = self.uart.transact(self.tx, 0, self.rx, left,
                                     left * self.byte_us + TIMEOUT_MARGIN_US)
            j = self._parse_present(0, got, j, now)
            more += 1
        self._read_alerts(now)
        missing = []
        for k in range(j, len(ids)):   # the first may have sent part of its reply
            s = self.servos[ids[k]]
            if k == j and p.pending():
                s.corrupt += 1
            else:
                s.timeouts += 1
            missing.append(k)
        return missing

    def _parse_present(self, start, got, j, now):
        """Status packets of a present-values SYNC_READ in ``rx[start:got]``; the number of
        servos answered so far (from ``j``), in list order."""
        p = self.parser
        ids = self.ids
        rx = self.rx
        for i in range(start, got):
            if not p.push(rx[i]):
                continue
            if j < len(ids) and p.id == ids[j] and p.nparams == PRESENT_LEN + 1:
                s = self.servos[ids[j]]
                self._take_present(s)
                self._status(s, p.param(0), now)
                j += 1
        return j
