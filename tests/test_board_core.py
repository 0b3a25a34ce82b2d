"""The ELF board's compiled core (hil/mcu/board_core.c): an ELF board is made only where it
is built from these sources, a run it cannot count to is refused at its start, and the
servo line's rules it carries out in C (a reply cut by PA1, a byte cut by a turn) hold."""
import dataclasses

import pytest

from hexhil.hil.mcu import board_core, board_layout
from hexhil.hil.mcu.board import Board
from hexhil.hil.mcu.elf_image import load_elf
from hexhil.protocol.errors import BadFile, UserError
from hexhil.run_summary import run
from tests.mcu_elf import build
from conftest import ROOT

FLAT = str(ROOT / "scenarios" / "flat-tripod.toml")


def test_the_library_is_built():
    board_core.require()
    assert board_core.library() is not None


def test_a_reply_arriving_while_pa1_is_high_is_lost_and_named(tmp_path):
    """The reply bytes queued in C are dropped when PA1 turns high under them."""
    summary, result = run(FLAT, duration_s=0.3, firmware=str(build(tmp_path, "cut_reply.c")))
    assert summary["faults"] == {"rx_while_transmitting": 1}, summary["faults"]
    assert result.ending.completed


def test_a_turn_at_txe_cuts_the_byte_on_the_wire(tmp_path):
    """PA1 turned low at TXE, not TC: C hands the turn to Python, which cuts the last byte
    of each of the 18 pings."""
    elf = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1", "TURN_AT_TXE=1")
    summary, _ = run(FLAT, duration_s=0.3, firmware=str(elf))
    assert summary["faults"]["tx_while_receiving"] == 18, summary["faults"]


def test_a_library_built_from_other_sources_is_refused_in_one_line(monkeypatch):
    """bc_t, Shared and the constants they share are hil/mcu/board_layout.py's, written as
    the header the library is built with: a library whose fingerprint is another layout's
    (here one more constant) is refused where a board is made, never read wrong."""
    header = board_layout.LAYOUT.header()
    assert "    uint32_t slot[256][3];\n" in header and "    struct set3 waits;\n" in header
    assert "    py_call_t py_call;\n" in header and "#define PY_SWITCHES 9\n" in header
    other = dataclasses.replace(board_layout.LAYOUT, constants=[("HX_OTHER", 1)])
    monkeypatch.setattr(board_core, "LAYOUT", other)
    lib, why = board_core._load()
    assert lib is None and "_board_core.so was built with other structs" in why, why
    monkeypatch.setattr(board_core, "_MISMATCH", why)
    with pytest.raises(BadFile, match=r"other structs .* builds it again$"):
        board_core.require()


def test_a_board_without_its_core_is_refused_in_one_line(tmp_path, monkeypatch):
    image = load_elf(build(tmp_path, "pend.c"))
    monkeypatch.setattr(board_core, "_LIB", None)     # as where the library is missing
    with pytest.raises(BadFile) as exc:
        Board(image, lambda data, closed: b"", lambda text: [])
    assert str(exc.value) == ("an ELF board needs compiled core _board_core.so, which is not "
                              "built: pip install -e . (or make) builds it")


def test_a_run_longer_than_the_board_counts_is_refused_at_its_start(tmp_path):
    """Virtual time in C is 64-bit femtoseconds: 9,223 s. A longer ELF run is refused in
    one line before the board boots."""
    with pytest.raises(UserError, match=r"^the ELF board counts virtual time to 9000 s "
                                        r"\(64-bit femtoseconds\); t=9001 s is beyond it$"):
        run(FLAT, duration_s=9001, firmware=str(build(tmp_path, "pend.c")))
