"""Dynamixel Protocol 2.0 packets, as spoken by the X series (XL430-W250-T).

Shared by the firmware (MicroPython) and the host, like protocol/dynamixel/v1.py: it imports
nothing beyond the language core, and the byte path (``Parser.push``, ``build_into``)
does not allocate.

Wire format (ROBOTIS e-manual, "Protocol 2.0"):
instruction ``FF FF FD 00 ID LEN_L LEN_H INSTR P1..PN CRC_L CRC_H`` and status
``FF FF FD 00 ID LEN_L LEN_H 55 ERR P1..PN CRC_L CRC_H``; LEN counts INSTR through CRC.
Byte stuffing: wherever ``FF FF FD`` appears from INSTR to the last parameter, an ``FD``
is added after it (and LEN counts it); the CRC-16 (polynomial 0x8005, the e-manual's "CRC
Calculation" table) covers the stuffed bytes from the first header byte. A receiver
checks the CRC first, then removes the stuffing.

Fast Sync Read and Fast Bulk Read are answered with ONE status packet (ID 0xFE) that
every addressed servo appends its block to: ``ERR ID DATA.. CRC_L CRC_H`` each, the
first ERR in the usual error position, each inner CRC the running CRC of the packet so
far and the last one the packet's own. Those packets are not stuffed (the SDK 4.1.0
reads them without unstuffing; decoding is by position).
"""

from protocol.dynamixel.stream import Packet as _Packet
from protocol.dynamixel.stream import (ACTION, FACTORY_RESET, PING, READ, REG_WRITE, SYNC_WRITE, WRITE,
                             StreamParser, sync_params, u16)

HEADER0 = 0xFF
HEADER1 = 0xFF
HEADER2 = 0xFD
RESERVED = 0x00
BROADCAST_ID = 0xFE
MAX_ID = 0xFC
MAX_PACKET = 1024           # whole packet, stuffed (DynamixelSDK's TX/RXPACKET_MAX_LEN)
INSTR_OFFSET = 7
PARAMS_OFFSET = 8
INTER_BYTE_TIMEOUT_US = 100000  # as Protocol 1.0: a long gap drops a partial packet

# Instructions (e-manual, Protocol 2.0, "Instruction"); PING to FACTORY_RESET and
# SYNC_WRITE are Protocol 1.0's (protocol/dynamixel/stream.py).
REBOOT = 0x08
CLEAR = 0x10
CONTROL_TABLE_BACKUP = 0x20
STATUS = 0x55
SYNC_READ = 0x82
FAST_SYNC_READ = 0x8A
BULK_READ = 0x92
BULK_WRITE = 0x93
FAST_BULK_READ = 0x9A

INSTRUCTION_NAMES = {
    PING: "PING", READ: "READ", WRITE: "WRITE", REG_WRITE: "REG_WRITE", ACTION: "ACTION",
    FACTORY_RESET: "FACTORY_RESET", REBOOT: "REBOOT", CLEAR: "CLEAR",
    CONTROL_TABLE_BACKUP: "CONTROL_TABLE_BACKUP", STATUS: "STATUS",
    SYNC_READ: "SYNC_READ", SYNC_WRITE: "SYNC_WRITE", FAST_SYNC_READ: "FAST_SYNC_READ",
    BULK_READ: "BULK_READ", BULK_WRITE: "BULK_WRITE", FAST_BULK_READ: "FAST_BULK_READ",
}
INSTRUCTIONS = {v: k for k, v in INSTRUCTION_NAMES.items()}

# Factory Reset options; Clear and Control Table Backup carry fixed keys (e-manual).
RESET_ALL = 0xFF
RESET_EXCEPT_ID = 0x01
RESET_EXCEPT_ID_BAUD = 0x02
CLEAR_MULTI_TURN = b"\x01\x44\x58\x4c\x22"
BACKUP_STORE = b"\x01\x43\x54\x52\x4c"     # "CTRL"
BACKUP_RESTORE = b"\x02\x43\x54\x52\x4c"

# Status error field: bit 7 Alert (see Hardware Error Status), bits 0-6 an error number.
ERR_RESULT_FAIL = 0x01
ERR_INSTRUCTION = 0x02
ERR_CRC = 0x03
ERR_DATA_RANGE = 0x04
ERR_DATA_LENGTH = 0x05
ERR_DATA_LIMIT = 0x06
ERR_ACCESS = 0x07
ALERT = 0x80

ERROR_NAMES = {
    ERR_RESULT_FAIL: "result_fail", ERR_INSTRUCTION: "instruction", ERR_CRC: "crc",
    ERR_DATA_RANGE: "data_range", ERR_DATA_LENGTH: "data_length",
    ERR_DATA_LIMIT: "data_limit", ERR_ACCESS: "access",
}


def error_names(error):
    """Names in a status packet's error field: the error number's, then "alert"."""
    out = []
    num = error & 0x7F
    if num:
        out.append(ERROR_NAMES.get(num, "error_%d" % num))
    if error & ALERT:
        out.append("alert")
    return out


def _crc_table():
    table = [0] * 256
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x8005) if c & 0x8000 else (c << 1)
        table[i] = c & 0xFFFF
    return table


CRC_TABLE = _crc_table()  # the e-manual's table, generated from its polynomial 0x8005


def crc16(buf, start, end, crc=0):
    """CRC-16 of buf[start:end], continuing from ``crc`` (0 for a new packet)."""
    table = CRC_TABLE
    for i in range(start, end):
        crc = ((crc << 8) ^ table[((crc >> 8) ^ buf[i]) & 0xFF]) & 0xFFFF
    return crc


def build_into(buf, dev_id, instr, params=b"", nparams=-1):
    """Write one stuffed packet into ``buf``; return its length.

    ``instr`` is the instruction (``STATUS`` for a reply, whose first parameter is the
    error field). ``nparams`` limits how much of ``params`` is used (default: all), so a
    firmware can keep one preallocated parameter buffer.
    """
    n = len(params) if nparams < 0 else nparams
    buf[0] = HEADER0
    buf[1] = HEADER1
    buf[2] = HEADER2
    buf[3] = RESERVED
    buf[4] = dev_id
    buf[INSTR_OFFSET] = instr
    w = PARAMS_OFFSET
    p1 = instr  # the two bytes before the current one, as sent before stuffing
    p2 = -1
    for i in range(n):
        b = params[i]
        buf[w] = b
        w += 1
        if b == 0xFD and p1 == 0xFF and p2 == 0xFF:
            buf[w] = 0xFD
            w += 1
        p2 = p1
        p1 = b
    length = w - INSTR_OFFSET + 2
    buf[5] = length & 0xFF
    buf[6] = length >> 8
    crc = crc16(buf, 0, w)
    buf[w] = crc & 0xFF
    buf[w + 1] = crc >> 8
    return w + 2


def packet(dev_id, instr, params=b""):
    """A packet as new ``bytes`` (host side and tests; the firmware uses build_into)."""
    buf = bytearray(2 * len(params) + 10)
    n = build_into(buf, dev_id, instr, params)
    return bytes(buf[:n])


def _u16(v):
    return bytes((v & 0xFF, (v >> 8) & 0xFF))


def ping(dev_id=BROADCAST_ID):
    return packet(dev_id, PING)


def read(dev_id, address, length):
    return packet(dev_id, READ, _u16(address) + _u16(length))


def write(dev_id, address, data):
    return packet(dev_id, WRITE, _u16(address) + bytes(data))


def reg_write(dev_id, address, data):
    return packet(dev_id, REG_WRITE, _u16(address) + bytes(data))


def action(dev_id=BROADCAST_ID):
    return packet(dev_id, ACTION)


def factory_reset(dev_id, option=RESET_ALL):
    return packet(dev_id, FACTORY_RESET, bytes((option,)))


def reboot(dev_id):
    return packet(dev_id, REBOOT)


def clear(dev_id, key=CLEAR_MULTI_TURN):
    return packet(dev_id, CLEAR, key)


def control_table_backup(dev_id, key=BACKUP_STORE):
    return packet(dev_id, CONTROL_TABLE_BACKUP, key)


def sync_read(address, length, ids, fast=False):
    """SYNC_READ (or FAST_SYNC_READ) of ``length`` bytes at ``address`` from ``ids``."""
    return packet(BROADCAST_ID, FAST_SYNC_READ if fast else SYNC_READ,
                  _u16(address) + _u16(length) + bytes(ids))


def sync_write(address, length, entries):
    """SYNC_WRITE to the broadcast ID; ``entries`` is a list of (id, data) pairs."""
    return packet(BROADCAST_ID, SYNC_WRITE,
                  sync_params(_u16(address) + _u16(length), length, entries))


def bulk_read(entries, fast=False):
    """BULK_READ (or FAST_BULK_READ); ``entries`` is a list of (id, address, length)."""
    params = bytearray()
    for dev_id, address, length in entries:
        params.append(dev_id)
        params.extend(_u16(address))
        params.extend(_u16(length))
    return packet(BROADCAST_ID, FAST_BULK_READ if fast else BULK_READ, params)


def bulk_write(entries):
    """BULK_WRITE; ``entries`` is a list of (id, address, data)."""
    params = bytearray()
    for dev_id, address, data in entries:
        params.append(dev_id)
        params.extend(_u16(address))
        params.extend(_u16(len(data)))
        params.extend(data)
    return packet(BROADCAST_ID, BULK_WRITE, params)


def status(dev_id, error=0, params=b""):
    return packet(dev_id, STATUS, bytes((error,)) + bytes(params))


def fast_status(blocks):
    """The one reply to a fast sync/bulk read: ``blocks`` is a list of (error, id, data).

    Not stuffed; each block ends with the running CRC of the packet up to it."""
    total = 8 + sum(4 + len(d) for _, _, d in blocks)
    buf = bytearray(total)
    buf[0:5] = bytes((HEADER0, HEADER1, HEADER2, RESERVED, BROADCAST_ID))
    length = total - 7
    buf[5] = length & 0xFF
    buf[6] = length >> 8
    buf[7] = STATUS
    w = 8
    crc = crc16(buf, 0, 8)
    for error, dev_id, data in blocks:
        buf[w] = error
        buf[w + 1] = dev_id
        buf[w + 2:w + 2 + len(data)] = data
        crc = crc16(buf, w, w + 2 + len(data), crc)
        w += 2 + len(data)
        buf[w] = crc & 0xFF
        buf[w + 1] = crc >> 8
        crc = crc16(buf, w, w + 2, crc)
        w += 2
    return bytes(buf)


def fast_blocks(params, lengths):
    """Split a fast reply's parameters (from its ERR on) into [(error, id, data)];
    ``lengths`` gives each block's data length in order (host side)."""
    out = []
    i = 0
    for n in lengths:
        if i + n + 4 > len(params) + 2:  # the last block's CRC is the packet's own
            break
        out.append((params[i], params[i + 1], bytes(params[i + 2:i + 2 + n])))
        i += n + 4
    return out


def u32(buf, i):
    return buf[i] | (buf[i + 1] << 8) | (buf[i + 2] << 16) | (buf[i + 3] << 24)


class Packet(_Packet):
    """A parsed packet (host convenience; the firmware reads the Parser's fields).

    ``params`` are unstuffed and start after INSTR (a status packet's ERR is params[0]);
    ``raw`` is the packet as it was on the wire."""

    __slots__ = ()

    @property
    def instr(self):
        return self.code

    @property
    def error(self):
        return self.params[0] if self.code == STATUS and self.params else 0

    def __repr__(self):
        return "Packet(id=%d, instr=0x%02X, params=%s)" % (self.id, self.instr, list(self.params))


class Parser(StreamParser):
    """Incremental Protocol 2.0 parser: push bytes, get packets.

    After ``push`` returns True the packet's fields are valid until the next push: ``id``,
    ``instr``, ``nparams`` and the unstuffed parameters in
    ``buf[PARAMS_OFFSET:PARAMS_OFFSET + nparams]`` (``raw_len`` is its length on the
    wire). Garbage is skipped up to the next ``FF FF FD 00`` that starts a valid packet;
    a bad length or CRC rejects the header and the scan resumes one byte later; a gap
    over 100 ms between bytes drops a partial packet.
    """

    def __init__(self):
        StreamParser.__init__(self, MAX_PACKET, INTER_BYTE_TIMEOUT_US, PARAMS_OFFSET)
        self.instr = 0
        self.raw_len = 0
        self.bad_crc = 0
        self.last_bad_crc_id = -1
        self.last_bad_crc_instr = -1

    def _scan(self):
        buf = self.buf
        while self._n:
            if buf[0] != HEADER0:
                self._skip_to(HEADER0)
                continue
            n = self._n
            if n >= 2 and buf[1] != HEADER1 or n >= 3 and buf[2] != HEADER2 \
                    or n >= 4 and buf[3] != RESERVED:
                self.garbage += 1
                self._drop(1)
                continue
            if n < 7:
                return False
            dev_id = buf[4]
            length = buf[5] | (buf[6] << 8)
            if dev_id == 0xFD or dev_id == 0xFF or length < 3 or length + 7 > MAX_PACKET:
                self._bad_length()
                continue
            total = length + 7
            if n < total:
                return False
            if crc16(buf, 0, total - 2) != buf[total - 2] | (buf[total - 1] << 8):
                self.bad_crc += 1
                self.last_reject = "bad_crc"
                self.last_bad_crc_id = dev_id
                self.last_bad_crc_instr = buf[INSTR_OFFSET]
                self._drop(1)
                continue
            self.id = dev_id
            self.instr = buf[INSTR_OFFSET]
            self.raw_len = total
            if self.instr == STATUS and dev_id == BROADCAST_ID:
                self.nparams = total - 2 - PARAMS_OFFSET  # a fast reply: not stuffed
            else:
                self.nparams = self._unstuff(total - 2)
            self.packets += 1
            self._consumed = total
            return True
        return False

    def _unstuff(self, end):
        """Remove stuffing from INSTR to ``end`` in place; the parameter count left.

        The CRC is already checked, so the packet's bytes after ``end`` are not needed."""
        buf = self.buf
        w = PARAMS_OFFSET
        a = buf[INSTR_OFFSET]
        b = buf[6]
        c = buf[5]  # the last three bytes read, newest first
        for i in range(PARAMS_OFFSET, end):
            x = buf[i]
            if not (x == 0xFD and a == 0xFD and b == 0xFF and c == 0xFF):
                buf[w] = x
                w += 1
            c = b
            b = a
            a = x
        return w - PARAMS_OFFSET

    def param_u32(self, i):
        return u32(self.buf, PARAMS_OFFSET + i)

    def current(self):
        """The complete packet just parsed, as a new Packet (allocates).

        ``raw`` is rebuilt for unstuffed packets, so it equals what was on the wire."""
        end = PARAMS_OFFSET + self.nparams
        params = bytes(self.buf[PARAMS_OFFSET:end])
        if self.instr == STATUS and self.id == BROADCAST_ID:
            raw = bytes(self.buf[0:self.raw_len])
        else:
            raw = packet(self.id, self.instr, params)
        return Packet(self.id, self.instr, params, raw)

    def counters(self):
        c = StreamParser.counters(self)
        c["bad_crc"] = self.bad_crc
        return c
