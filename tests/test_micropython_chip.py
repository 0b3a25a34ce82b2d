"""MicroPython's stm32 port as flashed (../shared/firmware/micropython/, built for this
board): a main.py laid into its internal-flash filesystem (hil/mcu/flash_fs.py) runs on the
emulated STM32F411 as on the board; its /flash is read back after the run."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from hexhil.hil.link.served_firmware import served_firmware
from hexhil.hil.mcu import flash_fs
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run_result import Ending
from hexhil.hil.scenario import load_scenario
from hexhil.protocol.errors import UserError
from conftest import ROOT

MICROPYTHON = ROOT.parent / "shared" / "firmware" / "micropython"
EMPTY_FS_ELF = MICROPYTHON / "micropython-hexhil-f411.elf"
MAINS = ROOT / "tests" / "micropython_chip"
PING_LINE = {"fw": "micropython", "main": "ping", "pings": 18, "mask": 524286,
             "freq": [100000000, 100000000, 25000000, 50000000]}


def run_main(main: Path, duration_s: float, switches=None, **files):
    """The empty-filesystem ELF with ``main`` as /flash/main.py on flat-tripod."""
    sim = Simulator(load_scenario(ROOT / "scenarios" / "flat-tripod.toml"), seed=0,
                    switches=switches)
    fw = served_firmware(EMPTY_FS_ELF, flash_files=FlashFiles(main=main, **files))
    return sim.run(duration_s, firmware=fw)


def first_json(result) -> dict:
    return next(json.loads(line) for line in result.stderr_tail.splitlines()
                if line.startswith("{"))


def test_the_image_is_the_same_bytes_for_the_same_files_and_reads_back(tmp_path):
    files = {"/main.py": b"print(1)\n", "/lib/util.py": b"X = 1\n"}
    a, b = flash_fs.image(files), flash_fs.image(files)
    assert a == b and len(a) == flash_fs.FS_SIZE
    assert a[0:3] == b"\xeb\xfe\x90" and a[510:512] == b"\x55\xaa"   # a FAT boot sector
    assert sorted(flash_fs.read_back(a, tmp_path)) == ["/lib/util.py", "/main.py"]
    assert (tmp_path / "lib" / "util.py").read_bytes() == b"X = 1\n"


def test_files_that_do_not_fit_and_a_flash_without_a_volume_are_one_line(tmp_path):
    with pytest.raises(UserError, match="does not fit|did not fit"):
        flash_fs.image({"/big.bin": bytes(70_000)})
    with pytest.raises(UserError, match="holds no FAT filesystem"):
        flash_fs.read_back(b"\xff" * flash_fs.FS_SIZE, tmp_path)


def test_main_py_in_flash_pings_the_18_servos_as_the_frozen_one_does(tmp_path):
    """The shared empty-filesystem ELF, unchanged, runs the ping main.py from /flash."""
    r = run_main(MICROPYTHON / "ping" / "main.py", 0.5)
    assert r.ending.kind is Ending.COMPLETED, r.ending
    assert first_json(r) == PING_LINE


def test_the_cli_lays_a_folder_and_reads_the_files_main_py_wrote_back(tmp_path):
    """--main and --fs lay the files, main.py imports a module from the folder and writes
    a file (os.sync flushes the port's flash cache: an erase and the programming), and
    --fs-out reads /flash back after the run."""
    lib = tmp_path / "fs"
    lib.mkdir()
    (lib / "answer.py").write_text("VALUE = 42\n")
    main = tmp_path / "main.py"
    main.write_text("import os, time, answer\n"
                    "with open('/flash/out.txt', 'w') as f:\n"
                    "    f.write('value %d' % answer.VALUE)\n"
                    "os.sync()\n"
                    "print('written')\n"
                    "while True:\n"
                    "    time.sleep_ms(100)\n")
    out = tmp_path / "back"
    done = subprocess.run([sys.executable, "-m", "hexhil.cli", "run",
                           str(ROOT / "scenarios" / "flat-tripod.toml"), "--firmware",
                           str(EMPTY_FS_ELF), "--main", str(main), "--fs", str(lib),
                           "--fs-out", str(out), "--duration", "1.0"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert (out / "out.txt").read_text() == "value 42"
    assert (out / "answer.py").read_text() == "VALUE = 42\n"
    assert (out / "main.py").read_text() == main.read_text()


def test_main_and_fs_need_a_micropython_elf():
    with pytest.raises(UserError, match="need a MicroPython STM32F411 ELF"):
        served_firmware(MICROPYTHON / "ping" / "main.py", flash_files=FlashFiles(
            main=MICROPYTHON / "ping" / "main.py"))


def test_the_garbage_collector_in_a_loop_with_interrupts_on():
    """gc.collect() back to back for 200 ms, SysTick and the UART interrupting it: every
    collection completes and the heap is whole afterwards."""
    r = run_main(MAINS / "gc_loop.py", 0.5)
    assert r.ending.kind is Ending.COMPLETED, r.ending
    done = first_json(r)
    assert done["collections"] > 50 and done["free"] > 50_000, done


def test_pin_interrupts_on_the_six_switches_count_every_edge():
    """Each switch pressed twice (PB0-PB5, staggered): both edges of each press reach its
    Pin.irq handler, and the 10 ms poll sees the same changes."""
    def pressed_us(i):
        return [(300_000 + 40_000 * i, 400_000 + 40_000 * i),
                (900_000 + 30_000 * i, 1_000_000 + 30_000 * i)]

    def switches(t_us):
        return sum(1 << i for i in range(6) if any(a <= t_us < b for a, b in pressed_us(i)))
    r = run_main(MAINS / "switch_irqs.py", 1.7, switches=switches)
    assert r.ending.kind is Ending.COMPLETED, r.ending
    assert first_json(r) == {"edges": [4] * 6, "changes": [4] * 6, "levels": [1] * 6}


def test_ticks_us_arithmetic_wraps_and_measures_sleeps():
    r = run_main(MAINS / "ticks.py", 0.3)
    t = first_json(r)
    assert (t["max"], t["wrap"], t["back"]) == (2 ** 30 - 1, 5, -5)
    assert 500 <= t["sleep_us_500"] < 600
    assert 19_000 <= t["sleep_ms_20"] <= 20_100      # whole SysTick ticks, as the port's delay
    assert 49_000 <= t["spin_ms_50"] <= 51_000


def test_the_board_definition_is_the_emulated_board():
    """firmware/micropython-board/HEXHIL_F411 says what hil/mcu/ emulates: the 25 MHz HSE
    through the PLL to 100 MHz, the REPL on USART1, the direction pin PA1 and the switches
    on PB0-PB5; the shared ELF was built from such a definition (its board name)."""
    import re

    from hexhil.hil.mcu import rcc
    from hexhil.hil.mcu.gpio_registers import SWITCH_PINS
    board = ROOT / "firmware" / "micropython-board" / "HEXHIL_F411"
    h = (board / "mpconfigboard.h").read_text()
    conf = (board / "stm32f4xx_hal_conf.h").read_text()

    def define(text, name):
        return re.search(rf"#define {name}\s+\(?(\w+|\"[^\"]*\")\)?", text).group(1)
    hse = int(define(conf, "HSE_VALUE"))
    m, n = int(define(h, "MICROPY_HW_CLK_PLLM")), int(define(h, "MICROPY_HW_CLK_PLLN"))
    p = int(define(h, "MICROPY_HW_CLK_PLLP").removeprefix("RCC_PLLP_DIV"))
    assert hse == rcc.HSE_HZ and hse // m * n // p == rcc.MAX_SYSCLK_HZ
    assert define(h, "MICROPY_HW_UART_REPL") == "PYB_UART_1"
    pins = dict(line.split(",") for line in (board / "pins.csv").read_text().splitlines()
                if line and not line.startswith("#") and not line.startswith(","))
    assert pins["SERVO_DIR"] == "PA1"
    assert [pins[f"SW_{s}"] for s in ("LF", "LM", "LH", "RF", "RM", "RH")] == \
        [f"PB{i}" for i in range(SWITCH_PINS)]
    name = define(h, "MICROPY_HW_BOARD_NAME").strip('"')
    assert f"; {name} with STM32F411xE\0".encode() in EMPTY_FS_ELF.read_bytes()   # banner


LOOP_50HZ = MAINS / "loop_50hz.py"


def test_the_deadline_figures_and_a_deadline_expectation_that_passes_and_one_that_fails(
        tmp_path):
    """A 50 Hz loop (a ping, some float work, sleep_ms to the next 20 ms): --json's
    ``deadline`` has its busy time per control cycle; a case with ``kind = "deadline"``
    passes at 15 ms of the period and fails at 0.5 ms, and ``hexhil test`` exits 1;
    ``--fs-out`` reads the case's /flash back into a folder of its own."""
    case = tmp_path / "deadline.toml"
    case.write_text(f'''[case]
name = "deadline"
scenario = "{ROOT / 'scenarios' / 'flat-tripod.toml'}"
duration_s = 0.5
firmware = "{EMPTY_FS_ELF}"
main = "{LOOP_50HZ}"

[[expect]]
name = "fits"
kind = "deadline"
max_busy_ms = 15.0
stat = "p99"

[[expect]]
name = "too tight"
kind = "deadline"
max_busy_ms = 0.5
''')
    done = subprocess.run([sys.executable, "-m", "hexhil.cli", "test", str(case),
                           "--fs-out", str(tmp_path / "flash")],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stdout + done.stderr
    assert (tmp_path / "flash" / "deadline" / "main.py").read_bytes() == LOOP_50HZ.read_bytes()
    rows = {line.split()[1]: line for line in done.stdout.splitlines()
            if line.startswith("deadline ")}
    assert rows["fits"].rstrip().endswith("pass") and "0 late" in rows["fits"]
    assert rows["too"].rstrip().endswith("FAIL")
    r = run_main(LOOP_50HZ, 0.5)
    d = r.firmware.other["mcu"]["deadline"]
    assert d["period_ms"] == 20.0 and d["late"] == 0 and d["cycles"] >= 20
    assert 0.5 < d["busy_p50_ms"] <= d["busy_p99_ms"] <= d["busy_max_ms"] < 15.0


def test_the_pytest_plugin_and_replay_take_the_flash_files(hexhil_run, tmp_path):
    """hexhil_run(main=..., fs_out=...) fills /flash as --main does and reads it back,
    check("deadline") judges the run, and hexhil replay --main replays its trace into the
    same ELF identically, its /flash read back too (without the main.py the firmware
    would format /flash instead: another run)."""
    done = hexhil_run(ROOT / "scenarios" / "flat-tripod.toml", duration_s=0.4,
                      firmware=EMPTY_FS_ELF, main=LOOP_50HZ, fs_out=tmp_path / "run")
    assert done.check("deadline", max_busy_ms=15.0, stat="p99").passed
    assert (tmp_path / "run" / "main.py").read_bytes() == LOOP_50HZ.read_bytes()
    from hexhil import replay
    r = replay.replay_firmware(done.trace, firmware=str(EMPTY_FS_ELF),
                               flash_files=FlashFiles(main=LOOP_50HZ, out=tmp_path / "replay"))
    assert r.identical and r.exchanges >= 20        # a line request a 20 ms cycle at least
    assert (tmp_path / "replay" / "main.py").read_bytes() == LOOP_50HZ.read_bytes()
    other = replay.replay_firmware(done.trace, firmware=str(EMPTY_FS_ELF))
    assert not other.identical


def test_an_erased_flash_is_formatted_at_the_first_boot_as_on_the_chip(tmp_path):
    """Without --main the port finds no filesystem, makes one through the FLASH interface
    (sector erases of 250 ms, word programming), writes boot.py and main.py, and starts its
    REPL: the shared README's console; --fs-out reads the new /flash back."""
    sim = Simulator(load_scenario(ROOT / "scenarios" / "flat-tripod.toml"), seed=0)
    fw = served_firmware(EMPTY_FS_ELF, flash_files=FlashFiles(out=tmp_path / "flash"))
    r = sim.run(3.0, firmware=fw)
    assert r.ending.kind is Ending.COMPLETED, r.ending
    assert r.stderr_tail == (
        "MicroPython v1.29.0-preview.731.g1c3c201149 on 2026-08-18; HEXHIL-F411 with "
        'STM32F411xE\nType "help()" for more information.\n>>> '), r.stderr_tail
    assert sorted(p.name for p in (tmp_path / "flash").iterdir()) == ["boot.py", "main.py"]


def test_the_frozen_ping_main_answers_within_0_1_s_on_a_formatted_flash(tmp_path):
    """The shared ping ELF on a /flash already formatted (--fs with an empty folder): the
    RTC's start-up (INITF, LSI) and the backup regulator's ready bit no longer hold the boot
    for a second; the 18 pings are done 0.1 s into the run (0.021 s on flat-tripod)."""
    sim = Simulator(load_scenario(ROOT / "scenarios" / "flat-tripod.toml"), seed=0)
    fw = served_firmware(MICROPYTHON / "micropython-hexhil-f411-ping.elf",
                         flash_files=FlashFiles(folder=tmp_path))
    r = sim.run(0.1, firmware=fw)
    assert r.ending.kind is Ending.COMPLETED, r.ending
    assert first_json(r) == PING_LINE
