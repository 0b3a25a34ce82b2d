# protocol/dynamixel/stream.py under the real micropython binary: the shared byte path, through a
# minimal subclass (packets are any two bytes starting 0xAA).
from protocol.dynamixel.stream import StreamParser
from tests.micropython.checks import check, done


class Pairs(StreamParser):
    def _scan(self):
        while self._n and self.buf[0] != 0xAA:
            self.garbage += 1
            self._drop(1)
        if self._n < 2:
            return False
        self.packets += 1
        self._consumed = 2
        return True

    def current(self):
        return self.buf[1]


p = Pairs(8, 1000, 0)
check(p.feed(b"\x01\xaa\x05\x02\xaa\x06") == [5, 6], "two packets through garbage")
check(p.garbage == 2 and p.packets == 2, "counted")
p.push(0xAA, 0)
check(p.pending() == 1, "partial held")
p.push(0x07, 5000)
check(p.timeouts == 1 and p.last_reject == "timeout", "timeout drops the partial packet")
p.reset()
p.feed(b"\x03\xaa")
check(p.flush() == [] and p.pending() == 0, "flush gives up on a partial packet")
print("packets", p.packets, "garbage", p.garbage)
done("stream")
