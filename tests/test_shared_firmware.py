"""The STM32 teams' own ELFs (../shared/firmware/, beside the repository: read in place, never
copied here) run unchanged on the emulated board as their README says: ST's HAL in a CubeMX
layout (cube) and FreeRTOS with ST's HAL (freertos). Each test checks the firmware's JSON
console line (the fields the README calls fixed exactly, the world-set ones by range), the
18 pings, servo 1 moved toward its goal, 500 ms measured on DWT within 2 %, and the same
serial digest twice. The runs are as short as the line allows: it comes at about 0.52 s."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from hexhil.run_summary import run
from hexhil.trace.reader import Trace
from conftest import ROOT

SHARED = ROOT.parent / "shared" / "firmware"
FLAT = str(ROOT / "scenarios" / "flat-tripod.toml")
DURATION_S = 0.6            # the summary line comes at 513 ms (cube) and 520 ms (freertos)
CUBE_DIGEST = "705393c12193620b"   # the README's, for any run past the p1 READ


def shared_elf(name: str) -> str:
    """The ELF ``name`` of ../shared/firmware/, or a failure saying where it should be."""
    elf = SHARED / name
    assert elf.is_file(), (f"{elf} is missing: the shared STM32 firmware folder must sit "
                           f"beside the repository ({SHARED})")
    return str(elf)


def summary_line(elf: str, tmp_path: Path) -> tuple[dict, dict]:
    """(the run's summary, the firmware's first JSON console line), the run checked."""
    trace = tmp_path / "run.mcap"
    summary, _ = run(FLAT, duration_s=DURATION_S, firmware=elf, out=str(trace))
    assert summary["ending"]["kind"] == "completed", summary["ending"]
    with Trace(trace) as t:
        lines = [json.loads(m.data)["text"] for m in t.messages(["/telemetry"])
                 if json.loads(m.data).get("event") == 0]
    line = next((ln for ln in lines if ln.startswith("{")), None)
    assert line is not None, lines
    return summary, json.loads(line)


def check_board_work(got: dict) -> None:
    """What cube and freertos both report: the clock, the pings, servo 1, DWT's 500 ms."""
    assert (got["pll"], got["sysclk"]) == (1, 100_000_000), got
    assert (got["pings"], got["mask"]) == (18, 524286), got       # ids 1..18 answered
    assert (got["torque"], got["sync"], got["uart_errors"], got["pressed"]) == (1, 1, 0, 0)
    assert got["goal"] == (412 if got["p0"] >= 512 else 612), got
    assert 0 <= got["p0"] <= 1023 and got["p1"] != got["p0"], got
    assert (got["p1"] - got["p0"]) * (got["goal"] - got["p0"]) > 0, got   # toward the goal
    assert abs(got["p1"] - got["p0"]) <= abs(got["goal"] - got["p0"]) + 5, got
    assert abs(got["cycles_500ms"] - 50_000_000) <= 0.02 * 50_000_000, got
    assert 500 <= got["ticks"] <= DURATION_S * 1000, got
    assert got["edges"] >= 0


def test_the_cubemx_hal_elf_prints_its_line_pings_18_moves_servo_1_and_repeats(tmp_path):
    elf = shared_elf("cube/cube.elf")
    first, got = summary_line(elf, tmp_path)
    check_board_work(got)
    assert (got["fw"], got["opt"], got["xfer"]) == ("cube", "-O2", "it"), got
    assert (got["pclk1"], got["slept_ms"], got["iwdg"]) == (50_000_000, 501, 0), got
    again, _ = run(FLAT, duration_s=DURATION_S, firmware=elf)
    assert first["serial_digest"] == again["serial_digest"]
    assert first["serial_digest"].startswith(CUBE_DIGEST), first["serial_digest"]


def test_the_freertos_elf_prints_its_line_pings_18_moves_servo_1_and_repeats(tmp_path):
    elf = shared_elf("freertos/freertos.elf")
    first, got = summary_line(elf, tmp_path)
    check_board_work(got)
    assert (got["fw"], got["kernel"], got["opt"], got["timebase"]) == \
        ("freertos", "V11.1.0+", "-O2", "TIM5"), got
    assert (got["slept_ms"], got["heap_free"]) == (500, 9808), got
    assert got["hal_ticks"] == got["ticks"], got           # TIM5 and SysTick both at 1 kHz
    assert abs(got["deg10"] - got["p1"] * 3000 / 1023) <= 1, got   # the FPU in a task
    assert got["polls"] > 0, got
    again, _ = run(FLAT, duration_s=DURATION_S, firmware=elf)
    assert first["serial_digest"] == again["serial_digest"] != ""


def test_the_cubemx_pages_expectation_file_passes_with_the_cube_elf(tmp_path):
    """docs/stm32-cubemx.md's `hexhil test` example, as a user copies it."""
    page = (ROOT / "docs" / "stm32-cubemx.md").read_text()
    case = re.search(r"```toml\n# tests/walk.toml\n(.*?)```", page, re.S)[1]
    tests = tmp_path / "tests"
    tests.mkdir()
    (tests / "walk.toml").write_text(case.replace('"../scenarios/', f'"{ROOT}/scenarios/'))
    proc = subprocess.run([sys.executable, "-m", "hexhil.cli", "test",
                           str(tests / "walk.toml"), "--firmware",
                           shared_elf("cube/cube.elf")], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "2 of 2 expectations passed" in proc.stdout, proc.stdout
