"""What both Dynamixel protocol modules share (protocol/dynamixel/v1.py, v2.py).

The byte path, MicroPython-compatible and allocation-free: a fixed buffer, bytes pushed
one at a time, a packet consumed only at the next push. A subclass supplies ``_scan``
(find and check a packet in ``buf[:_n]``; set ``_consumed`` and return True when one is
complete) and ``current`` (the packet just found, as an object). Beside it, the host-side
pieces both protocols build the same way: the parsed ``Packet`` and SYNC_WRITE's
parameters.
"""

# The instruction codes Protocol 2.0 kept from 1.0 (ROBOTIS e-manual, "Instruction").
PING = 0x01
READ = 0x02
WRITE = 0x03
REG_WRITE = 0x04
ACTION = 0x05
FACTORY_RESET = 0x06
SYNC_WRITE = 0x83


def u16(lo, hi):
    return lo | (hi << 8)


def sync_params(head, length, entries):
    """A SYNC_WRITE's parameters: ``head`` (its address and data length, as the protocol
    encodes them), then each entry's id and data; ``entries`` is a list of (id, data)
    pairs of ``length`` bytes each (host side; allocates)."""
    params = bytearray(head)
    for dev_id, data in entries:
        if len(data) != length:
            raise ValueError("sync_write entry for id %d has %d bytes, not %d"
                             % (dev_id, len(data), length))
        params.append(dev_id)
        params.extend(data)
    return params


class Packet:
    """A parsed packet (host convenience; the firmware reads the Parser's fields).

    ``code`` is the byte after the ID and length: Protocol 1.0's instruction or error byte,
    Protocol 2.0's instruction."""

    __slots__ = ("id", "code", "params", "raw")

    def __init__(self, dev_id, code, params, raw):
        self.id = dev_id
        self.code = code
        self.params = params
        self.raw = raw

    def __eq__(self, other):
        return type(other) is type(self) and self.raw == other.raw

    def __repr__(self):
        return "Packet(id=%d, code=0x%02X, params=%s)" % (self.id, self.code, list(self.params))


class StreamParser:
    """Buffer, inter-byte timeout and end-of-stream rescan of a Dynamixel parser."""

    def __init__(self, size, inter_byte_timeout_us, params_offset):
        self.buf = bytearray(size)
        self.id = -1
        self.nparams = 0
        self._params_at = params_offset
        self._n = 0
        self._consumed = 0
        self._last_t_us = None
        self._gap_us = inter_byte_timeout_us
        self.packets = 0
        self.garbage = 0
        self.bad_length = 0
        self.timeouts = 0
        self.last_reject = ""

    def reset(self):
        """Drop any partial packet (the line was turned round, say)."""
        self._n = 0
        self._consumed = 0

    def pending(self):
        """Bytes held of a packet not yet complete."""
        return self._n - self._consumed

    def param(self, i):
        return self.buf[self._params_at + i]

    def param_u16(self, i):
        at = self._params_at + i
        return self.buf[at] | (self.buf[at + 1] << 8)

    def counters(self):
        """The reject counts by name; a subclass adds its integrity check's."""
        return {
            "packets": self.packets,
            "garbage": self.garbage,
            "bad_length": self.bad_length,
            "timeouts": self.timeouts,
        }

    def _skip_to(self, header):
        """Drop the run up to the next ``header`` byte in one shift, counted as garbage
        (byte by byte, a rejected full-size packet cost n^2)."""
        buf = self.buf
        k = 1
        n = self._n
        while k < n and buf[k] != header:
            k += 1
        self.garbage += k
        self._drop(k)

    def _bad_length(self):
        """Reject a header whose length field cannot be; the scan resumes a byte later."""
        self.bad_length += 1
        self.last_reject = "bad_length"
        self._drop(1)

    def _drop(self, k):
        buf = self.buf
        n = self._n - k
        for i in range(n):
            buf[i] = buf[i + k]
        self._n = n

    def push(self, byte, t_us=-1):
        """Take one byte (received at ``t_us``, if known); True when a packet is complete."""
        if self._consumed:
            self._drop(self._consumed)
            self._consumed = 0
        if t_us >= 0:
            last = self._last_t_us
            if last is not None and self._n and t_us - last > self._gap_us:
                self.timeouts += 1
                self.last_reject = "timeout"
                self._n = 0
            self._last_t_us = t_us
        self.buf[self._n] = byte
        self._n += 1
        return self._scan()

    def flush(self):
        """End of stream: give up on the partial packet and rescan what it held.

        A garbage header with a large LEN can hide a valid packet behind it; a servo
        loses that packet, but a host decoding a capture wants it back.
        """
        out = []
        while True:
            if self._consumed:
                self._drop(self._consumed)
                self._consumed = 0
            if not self._n:
                return out
            if self._scan():
                out.append(self.current())
            elif self._n:
                self.garbage += 1
                self._drop(1)

    def feed(self, data, t_us=-1):
        """Push many bytes; return the complete packets as a list (allocates)."""
        out = []
        for b in data:
            if self.push(b, t_us):
                out.append(self.current())
        return out
