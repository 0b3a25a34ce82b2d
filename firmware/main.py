"""Firmware entry point: pick the HAL back end, boot, run the loop, report how it ended.

Real time on a serial device (``hexhil bus --world`` or a real bus):
``micropython firmware/main.py --serial /dev/pts/N [--config JSON]`` (hal/serial.py).
Simulator: ``micropython firmware/main.py PORT`` (or ``python -m firmware.main PORT``) with
the repository root on the import path; the port is the host's link (hil/link/firmware_process.py).
On the STM32 board, ``main.py`` runs at reset with the board back end.
"""
import json
import sys

from firmware import config
from firmware import telemetry
from firmware.controller import Controller
from protocol import sim_link

if sys.platform == "pyboard":   # MicroPython's stm32 port: the robot. Imported with main, so
    from firmware.hal.board import Board as _Robot   # hexhil --main lays it (flash_modules.py)


def _board():
    if sys.platform == "pyboard":
        return _Robot()
    if "--serial" in sys.argv:
        from firmware.hal.serial import Board
        from firmware.sensor_switches import attach
        return attach(Board())
    if sys.platform in ("linux", "darwin", "win32") and not _on_virtual_board():
        from firmware.hal.sim import Board
    else:
        from firmware.hal.board import Board
    return Board()


def _on_virtual_board():
    """``hexhil run --firmware firmware/main.py``: the unix port stands in for the board."""
    import os
    return os.getenv(sim_link.ENV_BOARD) == sim_link.BOARD_NAME


def _traceback(exc):
    try:
        import io
        buf = io.StringIO()
        sys.print_exception(exc, buf)  # MicroPython
        return buf.getvalue()
    except AttributeError:
        import traceback
        return "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))


def main(board=None):
    """Run the firmware on ``board`` (default: the back end this platform and argv pick).
    A ``sim_link.LinkError`` (the host refused a message or closed the link) is raised
    after the board is closed: nothing more can be told to the host."""
    board = board or _board()
    ctl = None
    try:
        ctl = Controller(board, config.merged(board.config()))
        ctl.boot()
        ctl.run()
    except sim_link.LinkError as exc:   # (a bare raise: not under the native emitter)
        raise exc
    except Exception as exc:  # reported to the host, which counts it; never silent
        board.event(sim_link.EVENT_EXCEPTION, _traceback(exc))
    finally:
        if ctl is not None:  # on a dead link it is dropped with the rest (hal/sim.py)
            board.event(sim_link.EVENT_STATS, json.dumps(telemetry.stats(ctl)))
        board.close()


def start(program=None):
    """``program`` (default ``main``) as a process: its exit status; a link error is one
    line on stderr, no traceback (docs/link.md)."""
    try:
        (program or main)()
    except sim_link.LinkError as exc:
        print("hexhil link:", exc.args[0] if exc.args else exc, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(start())
