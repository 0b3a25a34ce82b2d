"""Our firmware (firmware/main.py, its board back end hal/board.py) on MicroPython's stm32
port as flashed: ``--main firmware/main.py`` lays it with the modules it imports, compiled
(hil/mcu/flash_modules.py), on the shared empty-filesystem ELF, and it walks flat-tripod."""
from pathlib import Path

import pytest

from hexhil.hil.mcu import flash_fs, flash_modules
from hexhil.hil.mcu.deadline import is_sync_write
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.hil.run_result import Ending
from hexhil.hil.scenario import load_scenario
from hexhil.expect.case_runs import run_scenario
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.errors import UserError
from conftest import ROOT

EMPTY_FS_ELF = ROOT.parent / "shared" / "firmware" / "micropython" / "micropython-hexhil-f411.elf"
OUR_MAIN = ROOT / "firmware" / "main.py"
PING_MAIN = ROOT.parent / "shared" / "firmware" / "micropython" / "ping" / "main.py"
WALK_S = 1.2          # the boot is done at 0.22 s; a second of walking is a few centimetres


def walk(duration_s: float, trace: Path) -> dict:
    """``hexhil run --json``'s summary of our firmware on the chip (the master check on)."""
    sc = load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    summary, result = run_scenario(sc, 0, duration_s, "micropython", None, trace,
                                   firmware=str(EMPTY_FS_ELF),
                                   flash_files=FlashFiles(main=OUR_MAIN))
    assert result.ending.kind is Ending.COMPLETED, (result.ending, result.stderr_tail)
    return summary


@pytest.fixture(scope="module")
def walked(tmp_path_factory):
    return walk(WALK_S, tmp_path_factory.mktemp("walk") / "walk.mcap")


def test_main_lays_the_modules_it_imports_at_load_time_and_no_others():
    """The board back end (imported at module level on the stm32 port) and the Protocol 1.0
    master come; the host's back ends and Protocol 2.0 (imported in functions) do not, nor
    the empty package __init__ files (namespace packages)."""
    laid = set(flash_modules.imported_sources(OUR_MAIN))
    assert {"/firmware/hal/board.py", "/firmware/servo_bus/__init__.py",
            "/firmware/servo_bus/v1.py", "/firmware/controller.py",
            "/protocol/dynamixel/v1.py"} <= laid
    assert not laid & {"/firmware/hal/sim.py", "/firmware/hal/serial.py",
                       "/firmware/servo_bus/v2.py", "/protocol/dynamixel/v2.py",
                       "/firmware/__init__.py", "/firmware/main.py"}
    assert flash_modules.imported_sources(PING_MAIN) == {}   # a script alone lays itself


def test_the_compiled_firmware_fits_the_f411_flash_filesystem():
    files = flash_fs.files_of(FlashFiles(main=OUR_MAIN))
    assert files["/main.py"] == OUR_MAIN.read_bytes()
    mpys = [p for p in files if p != "/main.py"]
    assert mpys and all(p.endswith(".mpy") and files[p][:2] == b"M\x06" for p in mpys)
    assert len(flash_fs.image(files)) == flash_fs.FS_SIZE     # raises when it does not fit


def test_a_module_given_as_source_in_fs_is_not_laid_compiled_too(tmp_path):
    (tmp_path / "main.py").write_text("import helper\n")
    (tmp_path / "helper.py").write_text("X = 1\n")
    assert sorted(flash_fs.files_of(FlashFiles(main=tmp_path / "main.py"))) == [
        "/helper.mpy", "/main.py"]
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "helper.py").write_text("X = 2\n")
    files = flash_fs.files_of(FlashFiles(main=tmp_path / "main.py", folder=lib))
    assert sorted(files) == ["/helper.py", "/main.py"] and files["/helper.py"] == b"X = 2\n"


def test_a_module_that_does_not_parse_is_one_line_a_main_that_does_not_is_laid(tmp_path):
    """The port would say a broken main.py's SyntaxError on the board: it is laid as is."""
    (tmp_path / "main.py").write_text("import helper\n")
    (tmp_path / "helper.py").write_text("def broken(:\n")
    with pytest.raises(UserError, match="helper.py does not parse"):
        flash_fs.files_of(FlashFiles(main=tmp_path / "main.py"))
    (tmp_path / "main.py").write_text("import helper\nif :\n")
    assert flash_fs.files_of(FlashFiles(main=tmp_path / "main.py")) == {
        "/main.py": b"import helper\nif :\n"}


def test_sync_writes_of_both_protocols_start_control_cycles():
    entries = [(1, b"\x00\x02"), (2, b"\x00\x02")]
    assert is_sync_write(bytes(dxl.sync_write(30, 2, entries)))
    assert is_sync_write(bytes(dx2.sync_write(116, 2, entries)))
    assert not is_sync_write(bytes(dxl.ping(1))) and not is_sync_write(b"")


def test_our_firmware_walks_on_the_chip(walked):
    """Scan, configuration (the acknowledgements after the board's return delay) and
    walking: the body moves forward, no status byte is lost on the turned line."""
    assert walked["body"]["dx_m"] > 0.01, walked["body"]
    assert walked["faults"] == {} and walked["violations"]["total"] == 0, walked["violations"]


def test_its_control_cycles_are_from_sync_write_to_sync_write(walked):
    """The 50 Hz loop's cycles, measured between SYNC_WRITEs (its status reads come
    milliseconds later and start none); the interpreter's compute is charged."""
    d = walked["deadline"]
    assert d["cycles"] >= 25 and 19.0 <= d["period_ms"] <= 21.0, d
    assert 5.0 < d["busy_p50_ms"] <= d["busy_max_ms"], d


@pytest.mark.slow
def test_our_firmware_walks_0_3_m_in_30_s_on_the_chip(tmp_path):
    s = walk(30.0, tmp_path / "walk.mcap")
    assert s["body"]["dx_m"] >= 0.3, s["body"]


def test_margin_takes_fs_out_through_the_shared_option():
    from hexhil.cli import build_parser
    from hexhil.cli.run import flash_files

    argv = ["margin", "s.toml", "--expect", "e.toml", "--main", "m.py", "--fs-out", "back"]
    args = build_parser(argv).parse_args(argv)
    assert flash_files(args) == FlashFiles(main=Path("m.py"), out=Path("back"))
    case = FlashFiles(main=Path("case.py"), folder=Path("lib"))     # each option over the case's
    assert flash_files(args).over(case) == FlashFiles(Path("m.py"), Path("lib"), Path("back"))
