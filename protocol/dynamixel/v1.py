"""Dynamixel Protocol 1.0 packets, as spoken by the AX-12.

Shared by the firmware (MicroPython) and the host, so it imports nothing beyond the
language core. The byte path (``Parser.push``, ``build_into``) does not allocate: a
microcontroller calls it once per received byte.

Wire format (ROBOTIS e-manual, "Protocol 1.0"):
instruction ``FF FF ID LEN INSTR P1..PN CHK`` and status ``FF FF ID LEN ERR P1..PN CHK``,
LEN = N + 2, CHK = ~(ID + LEN + INSTR/ERR + P1 + ... + PN) & 0xFF.
"""

from protocol.dynamixel.stream import (ACTION, FACTORY_RESET, PING, READ, REG_WRITE, SYNC_WRITE, WRITE,
                             Packet, StreamParser, sync_params, u16)

HEADER = 0xFF
BROADCAST_ID = 0xFE
MAX_ID = 0xFD
MAX_PACKET = 259  # 4 header bytes + LEN up to 255
PARAMS_OFFSET = 5
STATUS_LEN = 6  # a status packet without parameters: FF FF ID LEN ERR CHK
INTER_BYTE_TIMEOUT_US = 100000  # a servo drops a partial packet after a 100 ms gap

# Instructions: the AX-12 supports exactly the seven Protocol 2.0 kept (protocol/dynamixel/stream.py).
INSTRUCTION_NAMES = {
    PING: "PING",
    READ: "READ",
    WRITE: "WRITE",
    REG_WRITE: "REG_WRITE",
    ACTION: "ACTION",
    FACTORY_RESET: "FACTORY_RESET",
    SYNC_WRITE: "SYNC_WRITE",
}
INSTRUCTIONS = {v: k for k, v in INSTRUCTION_NAMES.items()}

# Status-packet error bits (bit 7 is unused).
ERR_INPUT_VOLTAGE = 0x01
ERR_ANGLE_LIMIT = 0x02
ERR_OVERHEATING = 0x04
ERR_RANGE = 0x08
ERR_CHECKSUM = 0x10
ERR_OVERLOAD = 0x20
ERR_INSTRUCTION = 0x40

ERROR_BITS = (
    (ERR_INPUT_VOLTAGE, "input_voltage"),
    (ERR_ANGLE_LIMIT, "angle_limit"),
    (ERR_OVERHEATING, "overheating"),
    (ERR_RANGE, "range"),
    (ERR_CHECKSUM, "checksum"),
    (ERR_OVERLOAD, "overload"),
    (ERR_INSTRUCTION, "instruction"),
)


def error_names(error):
    """Names of the bits set in a status packet's error byte, lowest bit first."""
    return [name for bit, name in ERROR_BITS if error & bit]


def checksum(buf, start, end):
    """Protocol 1.0 checksum over buf[start:end] (ID through the last parameter)."""
    s = 0
    for i in range(start, end):
        s += buf[i]
    return (~s) & 0xFF


def build_into(buf, dev_id, code, params=b"", nparams=-1):
    """Write one packet (instruction or status) into ``buf``; return its length.

    ``code`` is the instruction for a master's packet, the error byte for a status
    packet. ``nparams`` limits how much of ``params`` is used (default: all of it), so
    a firmware can keep one preallocated parameter buffer.
    """
    n = len(params) if nparams < 0 else nparams
    buf[0] = HEADER
    buf[1] = HEADER
    buf[2] = dev_id
    buf[3] = n + 2
    buf[4] = code
    s = dev_id + n + 2 + code
    for i in range(n):
        b = params[i]
        buf[PARAMS_OFFSET + i] = b
        s += b
    buf[PARAMS_OFFSET + n] = (~s) & 0xFF
    return n + 6


def sync_write_into(buf, address, ids, first, second):
    """A SYNC_WRITE of two u16 values per ID (``first[j]``, ``second[j]`` for ``ids[j]``:
    Goal Position and Moving Speed) into ``buf`` in one pass; returns its length. The
    packet ``sync_write`` builds, without a parameter buffer copied a second time: the
    firmware sends it every cycle."""
    n = len(ids)
    nparams = 2 + 5 * n
    buf[0] = HEADER
    buf[1] = HEADER
    buf[2] = BROADCAST_ID
    buf[3] = nparams + 2
    buf[4] = SYNC_WRITE
    buf[5] = address
    buf[6] = 4
    s = BROADCAST_ID + nparams + 2 + SYNC_WRITE + address + 4
    k = 7
    for j in range(n):
        i = ids[j]
        a = first[j]
        b = second[j]
        a_lo = a & 0xFF
        a_hi = a >> 8
        b_lo = b & 0xFF
        b_hi = b >> 8
        buf[k] = i
        buf[k + 1] = a_lo
        buf[k + 2] = a_hi
        buf[k + 3] = b_lo
        buf[k + 4] = b_hi
        s += i + a_lo + a_hi + b_lo + b_hi
        k += 5
    buf[k] = (~s) & 0xFF
    return k + 1


def packet(dev_id, code, params=b""):
    """A packet as new ``bytes`` (host side and tests; the firmware uses build_into)."""
    buf = bytearray(len(params) + 6)
    build_into(buf, dev_id, code, params)
    return bytes(buf)


def ping(dev_id):
    return packet(dev_id, PING)


def read(dev_id, address, length):
    return packet(dev_id, READ, bytes((address, length)))


def write(dev_id, address, data):
    return packet(dev_id, WRITE, bytes((address,)) + bytes(data))


def reg_write(dev_id, address, data):
    return packet(dev_id, REG_WRITE, bytes((address,)) + bytes(data))


def action(dev_id=BROADCAST_ID):
    return packet(dev_id, ACTION)


def factory_reset(dev_id):
    return packet(dev_id, FACTORY_RESET)


def sync_write(address, data_len, entries):
    """SYNC_WRITE to the broadcast ID; ``entries`` is a list of (id, data) pairs."""
    return packet(BROADCAST_ID, SYNC_WRITE, sync_params((address, data_len), data_len, entries))


def status(dev_id, error=0, params=b""):
    return packet(dev_id, error, params)


def status_ok(parser, data, start, end, dev_id, nparams):
    """Whether ``data[start:end]`` holds a status packet of ``dev_id`` with ``nparams``
    parameters, parsed into ``parser`` (its fields stay valid): the bus master's test of a
    reply (firmware/servo_bus/v1.py), which the host of link version 2 applies to retry a
    read exactly when the master would (docs/link.md "R reads")."""
    if end - start < STATUS_LEN + nparams:
        return False
    parser.reset()
    if parser.take_whole(data, start, end):
        return parser.id == dev_id and parser.nparams == nparams
    for i in range(start, end):
        if parser.push(data[i]) and parser.id == dev_id and parser.nparams == nparams:
            return True
    return False


class Parser(StreamParser):
    """Incremental Protocol 1.0 parser: push bytes, get packets.

    After ``push`` returns True the packet's fields are valid until the next push:
    ``id``, ``code`` (instruction or error byte), ``nparams`` and the parameters in
    ``buf[PARAMS_OFFSET:PARAMS_OFFSET + nparams]``. Garbage is skipped up to the next
    ``FF FF`` that starts a valid packet; packets with a bad length or checksum are
    rejected and counted; a gap over 100 ms between bytes drops a partial packet.
    """

    def __init__(self):
        StreamParser.__init__(self, MAX_PACKET, INTER_BYTE_TIMEOUT_US, PARAMS_OFFSET)
        self.code = 0
        self.bad_checksum = 0
        self.last_bad_checksum_id = -1

    def take_whole(self, data, start, end):
        """Take ``data[start:end]`` at once if the parser holds nothing and it is exactly one
        valid packet: the same state as pushing its bytes one by one (True at the last),
        without a call per byte. Returns False and takes nothing otherwise (push them)."""
        m = end - start
        if (self._n or m < 6 or data[start] != HEADER or data[start + 1] != HEADER
                or data[start + 2] == HEADER or data[start + 3] < 2 or data[start + 3] + 4 != m
                or checksum(data, start + 2, end - 1) != data[end - 1]):
            return False
        self.buf[0:m] = data[start:end]
        self._n = self._consumed = m
        self.id = data[start + 2]
        self.code = data[start + 4]
        self.nparams = m - 6
        self.packets += 1
        return True

    def _scan(self):
        buf = self.buf
        while self._n:
            if buf[0] != HEADER:
                self._skip_to(HEADER)
                continue
            if self._n < 2:
                return False
            if buf[1] != HEADER:
                self.garbage += 1
                self._drop(1)
                continue
            if self._n < 3:
                return False
            if buf[2] == HEADER:  # FF FF FF: the packet may start one byte later
                self.garbage += 1
                self._drop(1)
                continue
            if self._n < 4:
                return False
            length = buf[3]
            if length < 2:
                self._bad_length()
                continue
            total = length + 4
            if self._n < total:
                return False
            if checksum(buf, 2, total - 1) != buf[total - 1]:
                self.bad_checksum += 1
                self.last_reject = "bad_checksum"
                self.last_bad_checksum_id = buf[2]
                self._drop(1)
                continue
            self.id = buf[2]
            self.code = buf[4]
            self.nparams = length - 2
            self.packets += 1
            self._consumed = total
            return True
        return False

    def current(self):
        """The complete packet just parsed, as a new Packet (allocates)."""
        end = PARAMS_OFFSET + self.nparams
        return Packet(self.id, self.code, bytes(self.buf[PARAMS_OFFSET:end]),
                      bytes(self.buf[0:end + 1]))

    def counters(self):
        c = StreamParser.counters(self)
        c["bad_checksum"] = self.bad_checksum
        return c
