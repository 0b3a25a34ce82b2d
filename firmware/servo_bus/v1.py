"""AX-12 bus master: scan, configure, one SYNC_WRITE per cycle, rotating status reads.

Packets are built with protocol/dynamixel/v1.py's ``build_into`` and parsed with its
``Parser`` into preallocated buffers: no per-byte allocation. On a line that echoes the
master's own bytes (single-wire adapter without a direction circuit) the master skips
exactly the bytes it sent, which it knows, before parsing the reply. Timeouts are bus
time: the reply's wire time plus the servos' return delay plus a margin.
MicroPython-compatible.
"""
from protocol.dynamixel import ax12
from protocol.dynamixel import v1 as dxl

TIMEOUT_MARGIN_US = 100
EEPROM_SETTLE_US = 10_000       # a real AX-12 is deaf for a few ms after an EEPROM write
STATUS_LEN = dxl.STATUS_LEN     # FF FF ID LEN ERR CHK, without parameters
PRESENT_ADDR = ax12.PRESENT_POSITION
PRESENT_LEN = 6                 # present position, speed and load
CRITICAL_BITS = dxl.ERR_OVERHEATING | dxl.ERR_OVERLOAD  # the AX-12's default shutdown set
OK = 0
TIMEOUT = 1
CORRUPT = 2


class ServoStats:
    """Per-servo counters and last readings (AX-12 units)."""

    __slots__ = ("id", "present", "timeouts", "corrupt", "replies", "error_bits",
                 "errors", "last_ok_us", "critical_run", "position", "speed", "load")

    def __init__(self, dev_id):
        self.id = dev_id
        self.present = False
        self.timeouts = 0
        self.corrupt = 0
        self.replies = 0
        self.errors = 0          # status packets carrying any error bit
        self.error_bits = 0      # OR of every error byte seen
        self.last_ok_us = 0
        self.critical_run = 0    # consecutive statuses with a shutdown bit set
        self.position = -1
        self.speed = 0
        self.load = 0


class Master:
    present_addr = PRESENT_ADDR      # what read_present reads
    present_len = PRESENT_LEN

    def __init__(self, uart, ids, baud=1000000, echo=None, retries=1):
        self.uart = uart
        self.ids = ids
        self.servos = {}
        for i in ids:
            self.servos[i] = ServoStats(i)
        self.byte_us = (10 * 1000000 + baud - 1) // baud
        self.echo = echo                 # None: detect on the first transaction
        self.retries = retries
        self.return_delay_us = 500       # factory default until configured
        self.delay_set_us = 0            # the return delay configure_eeprom writes (2 us units)
        self.tx = bytearray(dxl.MAX_PACKET)
        self.rx = bytearray(dxl.MAX_PACKET * 2)
        self.small = bytearray(8)
        self.parser = dxl.Parser()
        self.transactions = 0
        self.echo_mismatch = 0
        self.sync_writes = 0
        self.error = 0                   # error byte of the last good status

    # --- one transaction -------------------------------------------------------------
    def _transact(self, dev_id, n, nparams, now):
        """Send ``tx[:n]`` to ``dev_id`` and parse its status with ``nparams`` parameters.

        ``now`` is the board (for the time of a good reply). Returns OK, TIMEOUT or CORRUPT; on OK the
        parameters are in ``parser.buf`` from PARAMS_OFFSET.
        """
        want = STATUS_LEN + nparams
        nrx, timeout = self._shape(n, nparams)
        got = self.uart.transact(self.tx, n, self.rx, nrx, timeout)
        self.transactions += 1
        start = 0
        if self.echo is None:
            self.echo = got >= n and self.rx[:n] == self.tx[:n]
            if not self.echo and got > want:
                got = want
        if self.echo:
            start = n
            if got >= n:
                for i in range(n):
                    if self.rx[i] != self.tx[i]:
                        self.echo_mismatch += 1
                        break
        s = self.servos.get(dev_id)
        if got - start < want:
            if s is not None:
                if got > start:
                    s.corrupt += 1
                else:
                    s.timeouts += 1
            return TIMEOUT if got <= start else CORRUPT
        p = self.parser
        if not dxl.status_ok(p, self.rx, start, got, dev_id, nparams):
            if s is not None:
                s.corrupt += 1
            return CORRUPT
        self.error = p.code
        if s is not None:
            s.replies += 1
            s.present = True
            s.last_ok_us = now.ticks_us()
            if p.code:
                s.errors += 1
                s.error_bits |= p.code
            if p.code & CRITICAL_BITS:
                s.critical_run += 1
            else:
                s.critical_run = 0
        return OK

    def _shape(self, n, nparams):
        """(nrx, timeout_us) of a transaction of ``n`` bytes answered with ``nparams``: the
        reply after our echo (or room to see one while the echo is unknown), its wire time,
        the return delay and a margin."""
        nrx = (n if self.echo or self.echo is None else 0) + STATUS_LEN + nparams
        return nrx, nrx * self.byte_us + self.return_delay_us + TIMEOUT_MARGIN_US

    def _retry(self, dev_id, n, nparams, now):
        r = self._transact(dev_id, n, nparams, now)
        k = 0
        while r != OK and k < self.retries:
            r = self._transact(dev_id, n, nparams, now)
            k += 1
        return r

    # --- instructions --------------------------------------------------------------
    def ping(self, dev_id, now):
        n = dxl.build_into(self.tx, dev_id, dxl.PING, b"", 0)
        return self._retry(dev_id, n, 0, now) == OK

    def write(self, dev_id, address, data, ndata, now):
        """WRITE ``data[:ndata]`` at ``address``; True when the servo acknowledged it."""
        buf = self.small if ndata < len(self.small) else bytearray(ndata + 1)
        buf[0] = address
        for i in range(ndata):
            buf[1 + i] = data[i]
        n = dxl.build_into(self.tx, dev_id, dxl.WRITE, buf, ndata + 1)
        return self._retry(dev_id, n, 0, now) == OK

    def read(self, dev_id, address, length, now):
        """READ; on success the data is at ``parser.buf[PARAMS_OFFSET:]``."""
        self.small[0] = address
        self.small[1] = length
        n = dxl.build_into(self.tx, dev_id, dxl.READ, self.small, 2)
        return self._retry(dev_id, n, length, now) == OK

    def read_cycle(self, policy, now):
        """A cycle's status reads: a few servos, as the fault policy rotates them."""
        policy.read_rotating(self, now)

    def read_present(self, dev_id, now):
        """Present position, speed and load into the servo's stats; True on success."""
        if not self.read(dev_id, self.present_addr, self.present_len, now):
            return False
        self._take_present(self.servos[dev_id])
        return True

    def read_present_many(self, reads, now):
        """A cycle's status reads: ``reads`` lists (servo ID, index of an earlier read that,
        unless it succeeded, skips this one; -1 for none); returns True, False or None
        (skipped) for each. A UART that carries them all in one exchange (hal/sim.py on
        link version 2: ``reads``) gets them up front; its replies are then taken here one
        by one, by the same code as single reads, so every counter and retry is the same."""
        batch = getattr(self.uart, "reads", None)
        if batch is not None and self.echo is not None:
            plan = []
            for dev_id, skip in reads:
                n = dxl.build_into(self.tx, dev_id, dxl.READ, self._present_req(), 2)
                nrx, timeout = self._shape(n, self.present_len)
                plan.append((dev_id, self.present_len, skip, nrx, timeout, bytes(self.tx[:n])))
            batch(plan, self.retries, self.echo)
        out = []
        for dev_id, skip in reads:
            if skip >= 0 and out[skip] is not True:
                out.append(None)
            else:
                out.append(self.read_present(dev_id, now))
        if batch is not None and self.echo is not None:
            self.uart.reads_done()
        return out

    def _present_req(self):
        self.small[0] = self.present_addr
        self.small[1] = self.present_len
        return self.small

    def _take_present(self, s):
        """The present values in the reply just parsed into ``s``."""
        p = self.parser
        s.position = p.param_u16(0)
        s.speed = p.param_u16(2)
        s.load = p.param_u16(4)

    def sync_write(self, positions, speeds, now):
        """One SYNC_WRITE of goal position + moving speed (AX-12 units) for every servo."""
        n = dxl.sync_write_into(self.tx, ax12.GOAL_POSITION, self.ids, positions, speeds)
        self._send_unanswered(n)
        return n

    def _send_unanswered(self, n):
        """Send ``tx[:n]``, which no servo answers (SYNC_WRITE), consuming our echo."""
        if self.echo:
            # The echo must be consumed: a transaction expecting only our own bytes back.
            got = self.uart.transact(self.tx, n, self.rx, n, n * self.byte_us + TIMEOUT_MARGIN_US)
            self.transactions += 1
            if got != n or self.rx[:n] != self.tx[:n]:
                self.echo_mismatch += 1
        else:
            self.uart.write(self.tx, n)
        self.sync_writes += 1

    # --- boot ------------------------------------------------------------------------
    def scan(self, now):
        """PING every expected ID; return the list of IDs that answered."""
        found = []
        for i in self.ids:
            if self.ping(i, now):
                found.append(i)
        return found

    def configure_eeprom(self, dev_id, cw_limit, ccw_limit, now):
        """Return delay ``delay_set_us`` and angle limits (EEPROM, one WRITE); True when
        acknowledged. The servo then ignores packets for a few ms: wait EEPROM_SETTLE_US
        before talking to it."""
        d = self.small
        d[0] = self.delay_set_us // 2
        d[1] = cw_limit & 0xFF
        d[2] = cw_limit >> 8
        d[3] = ccw_limit & 0xFF
        d[4] = ccw_limit >> 8
        return self.write(dev_id, ax12.RETURN_DELAY_TIME, bytes(d[:5]), 5, now)

    def configure_ram(self, dev_id, margin, slope, now):
        """Compliance and torque on (RAM, one WRITE); True when acknowledged."""
        ram = bytes((1, 0, margin, margin, slope, slope))  # torque, LED, margins, slopes
        return self.write(dev_id, ax12.TORQUE_ENABLE, ram, 6, now)

    def counters(self):
        t = c = e = 0
        for s in self.servos.values():
            t += s.timeouts
            c += s.corrupt
            e += s.errors
        return t, c, e
