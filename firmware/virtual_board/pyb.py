"""Stand-in for ``pyb`` on the virtual board: ``pyb.CAN(1)`` on the run's CAN bus (the
stm32 port's API as firmware/hal/board.py uses it). Frames sent are posted at once;
frames for the board arrive with its sleeps and ``any()`` (vboard.py)."""
import vboard


class CAN:
    NORMAL = 0
    LOOPBACK = 1
    SILENT = 2
    MASK16 = 0
    LIST16 = 1
    MASK32 = 2
    LIST32 = 3

    def __init__(self, bus, mode=None, baudrate=500000, **kw):
        if bus != 1:
            raise ValueError("CAN(%s) doesn't exist: the board has CAN bus 1" % bus)
        self.board = vboard.board()

    def init(self, *args, **kw):
        pass

    def setfilter(self, *args, **kw):
        """Every frame is accepted (filters are not emulated)."""

    def send(self, data, arb_id, timeout=0, rtr=False):
        self.board.post_can(arb_id, bytes(data))

    def any(self, fifo=0):
        return self.board.can_any()

    def recv(self, fifo=0, list=None, timeout=5000):
        """(id, rtr, fmi, data) of the oldest frame; OSError after ``timeout`` ms without one."""
        b = self.board
        if not b.can_rx and timeout:
            b.sleep_until(b.now_us + timeout * 1000)
        if not b.can_rx:
            raise OSError(110)  # ETIMEDOUT
        arb_id, data = b.can_rx.pop(0)
        return (arb_id, False, 0, data)
