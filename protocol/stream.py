"""The byte path both Dynamixel parsers share (protocol/dynamixel.py, dynamixel2.py).

MicroPython-compatible and allocation-free: a fixed buffer, bytes pushed one at a time,
a packet consumed only at the next push. A subclass supplies ``_scan`` (find and check a
packet in ``buf[:_n]``; set ``_consumed`` and return True when one is complete) and
``current`` (the packet just found, as an object).
"""


class StreamParser:
    """Buffer, inter-byte timeout and end-of-stream rescan of a Dynamixel parser."""

    def __init__(self, size, inter_byte_timeout_us):
        self.buf = bytearray(size)
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
