"""HAL back end for a real serial device under the unix port: the firmware on its own clock.

``micropython firmware/main.py --serial /dev/pts/N`` (``hexhil bus --world`` prints the
pty; a USB adapter's /dev/ttyUSB0 reaches a real bus) runs the board's code path: the
transaction of hal/realtime.py and the wall clock of hal/base.py, shared with hal/board.py,
over a raw tty
(``termios.setraw``; reads byte by byte after ``select.poll`` says one is there, since a
unix-port file has no non-blocking read). The six limit switches are read from the
sensor node (hil/servobus/switch_node.py, docs/servo-bus.md) once per cycle, right after the
sleep, by the reader the firmware attaches as ``switch_reader`` (firmware/sensor_switches.py:
the HAL does not import the application). CAN frames are counted and dropped (hal/base.py
``CAN``), as on the F411. A hung-up line ends the loop at the next sleep.
MicroPython-compatible (unix port, CPython).
"""
import select
import sys
import termios

from firmware.hal import base
from firmware.hal.realtime import HalfDuplexUART

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


def _args(argv):
    """``--serial PATH`` [``--baud N``] [``--config JSON``] [``--sensor-id N``]
    [``--latency-us N``]."""
    out = {"--baud": "1000000", "--config": "{}", "--sensor-id": "",
           "--latency-us": str(LATENCY_US)}
    i = 0
    while i < len(argv) - 1:
        if argv[i] in out or argv[i] == "--serial":
            out[argv[i]] = argv[i + 1]
            i += 1
        i += 1
    return out


class Board(base.Board):
    def __init__(self, argv=None):
        import json

        a = _args(sys.argv if argv is None else argv)
        self.baud = int(a["--baud"])
        self.tty = TtyUART(a["--serial"], self.baud)
        self.uart = HalfDuplexUART(self.tty, self.baud, None, int(a["--latency-us"]))
        self.can = base.CAN()
        self.switch_bits = 0
        self.switches = [base.Switch(self, i) for i in range(6)]
        self.sensor_id = int(a["--sensor-id"]) if a["--sensor-id"] else None
        self.switch_reader = None  # f(board) -> switch bits or None, set by the firmware
        self.ended = False
        self._config = json.loads(a["--config"])

    def config(self):
        """Overrides of firmware/config.py given with ``--config JSON``."""
        return self._config

    def sleep_until(self, t_us):
        """Sleep on the wall clock, then read the switches for the cycle that starts."""
        base.Board.sleep_until(self, t_us)
        if self.switch_reader is not None:
            bits = self.switch_reader(self)
            if bits is not None:
                self.switch_bits = bits
        self.ended = self.tty.hung

    def close(self):
        self.tty.close()
