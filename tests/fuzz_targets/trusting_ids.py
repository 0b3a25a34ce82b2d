"""Our firmware with a bug planted for the bus fuzzer (tests/test_bus_fuzz.py, docs/fuzzing.md):
its bus master accepts a status packet whatever ID it carries, and files the position it
reads under that ID in its servo table. A reply carrying another servo's ID lands in that
servo's row; one carrying an ID no servo has raises KeyError, and the firmware stops.
Run in process (``hexhil fuzz --in-process``): ``main(board)`` plants the bug for its run.
It reads each status itself (link version 2's reads are judged on the host by our master's
rule, which this one no longer follows)."""
from firmware import main as firmware_main
from firmware.hal import sim
from firmware.servo_bus import v1
from protocol.dynamixel import v1 as dxl


class TrustingProtocol:
    """protocol/dynamixel/v1.py as the buggy master sees it: ``status_ok`` skips the ID."""

    def __getattr__(self, name):
        return getattr(dxl, name)

    @staticmethod
    def status_ok(parser, data, start, end, dev_id, nparams):
        if end - start < dxl.STATUS_LEN + nparams:
            return False
        parser.reset()
        return parser.take_whole(data, start, end) and parser.nparams == nparams


def _take_present_by_packet_id(self, s):
    """The bug: the row is the packet's ID, not the ID the master asked."""
    v1.Master._take_present_checked(self, self.servos[self.parser.id])


def main(board):
    board.uart = sim.HalfDuplexUART(board.link)
    v1.Master._take_present_checked = v1.Master._take_present
    v1.Master._take_present, v1.dxl = _take_present_by_packet_id, TrustingProtocol()
    try:
        firmware_main.main(board)
    finally:
        v1.Master._take_present, v1.dxl = v1.Master._take_present_checked, dxl
        del v1.Master._take_present_checked
