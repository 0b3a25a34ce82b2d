"""HAL back end for a real serial device under the unix port: the firmware on its own clock.

``micropython firmware/main.py --serial /dev/pts/N`` (``hexhil bus --world`` prints the
pty; a USB adapter's /dev/ttyUSB0 reaches a real bus) runs the board's code path: the
transaction and timing of hal/realtime.py, shared with hal/board.py, over a raw tty
(``termios.setraw``; reads byte by byte after ``select.poll`` says one is there, since a
unix-port file has no non-blocking read). The six limit switches are read from the
sensor node (hil/sensor_node.py, docs/servo-bus.md) once per cycle, right after the
sleep, through the same bus master as the servos. CAN frames are counted and dropped,
as on the F411. A hung-up line ends the loop at the next sleep. MicroPython-compatible (unix port, CPython).
"""
import select
import sys
import termios

from firmware import servo_bus
from firmware.hal.realtime import HalfDuplexUART, WallClock

SENSOR_ID = 100            # the sensor node's factory ID
SWITCHES_ADDR = 26         # its Switches byte, bit i = leg i pressed
LATENCY_US = 10000         # a pty under load or a USB adapter delivers a reply this late, at most
BAUD_FLAGS = {1000000: "B1000000", 115200: "B115200", 57600: "B57600"}


class TtyUART:
    """``write``, ``any``, ``read``, ``readinto`` of a raw tty, as machine.UART gives them."""

    def __init__(self, path, baud):
        self.f = open(path, "r+b")
        fd = self.f.fileno()
        termios.setraw(fd)
        flag = BAUD_FLAGS.get(baud)
        if flag is not None and hasattr(termios, flag):
            attr = termios.tcgetattr(fd)
            attr[4] = attr[5] = getattr(termios, flag)
            termios.tcsetattr(fd, termios.TCSANOW, attr)
        self.poller = select.poll()
        self.poller.register(self.f, select.POLLIN)
        self.one = bytearray(1)
        self.hung = False          # the other end closed the line

    def write(self, data):
        try:
            self.f.write(data)
        except OSError:
            self.hung = True

    def any(self):
        for _, ev in self.poller.poll(0):
            if ev & (select.POLLHUP | select.POLLERR):
                self.hung = True
                return 0
            return 1
        return 0

    def wait(self):
        """Block until a byte comes, at most 1 ms (poll's unit)."""
        self.poller.poll(1)

    def read(self):
        self.f.readinto(self.one)
        return bytes(self.one)

    def readinto(self, mv):
        if not len(mv):
            return 0
        self.f.readinto(self.one)
        mv[0] = self.one[0]
        return 1

    def close(self):
        self.f.close()


class _Switch:
    def __init__(self, board, bit):
        self.board = board
        self.bit = bit

    def value(self):
        return 1 if self.board.switch_bits & self.bit else 0


class _NoCAN:
    """No CAN controller on this line: frames are counted and dropped."""

    def __init__(self):
        self.dropped = 0

    def send(self, data, arb_id):
        self.dropped += 1

    def any(self):
        return False


def _args(argv):
    """``--serial PATH`` [``--baud N``] [``--config JSON``] [``--sensor-id N``]
    [``--latency-us N``]."""
    out = {"--baud": "1000000", "--config": "{}", "--sensor-id": str(SENSOR_ID),
           "--latency-us": str(LATENCY_US)}
    i = 0
    while i < len(argv) - 1:
        if argv[i] in out or argv[i] == "--serial":
            out[argv[i]] = argv[i + 1]
            i += 1
        i += 1
    return out


class Board(WallClock):
    def __init__(self, argv=None):
        import json

        a = _args(sys.argv if argv is None else argv)
        baud = int(a["--baud"])
        self.tty = TtyUART(a["--serial"], baud)
        self.uart = HalfDuplexUART(self.tty, baud, None, int(a["--latency-us"]))
        self.can = _NoCAN()
        self.switch_bits = 0
        self.switches = [_Switch(self, 1 << i) for i in range(6)]
        self.sensor_id = int(a["--sensor-id"])
        self.sensor = servo_bus.Master(self.uart, [self.sensor_id], baud)
        self.switch_reads = 0
        self.ended = False
        self._config = json.loads(a["--config"])

    def config(self):
        """Overrides of firmware/config.py given with ``--config JSON``."""
        return self._config

    def _read_switches(self):
        if self.sensor.read(self.sensor_id, SWITCHES_ADDR, 1, self):
            self.switch_bits = self.sensor.parser.param(0) & 0x3F
            self.switch_reads += 1

    def sleep_until(self, t_us):
        """Sleep on the wall clock, then read the switches for the cycle that starts."""
        WallClock.sleep_until(self, t_us)
        self._read_switches()
        self.ended = self.tty.hung

    def event(self, kind, text):
        print("event", kind, text)

    def close(self):
        self.tty.close()
