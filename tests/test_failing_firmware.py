"""A firmware that crashes, hangs, exits early or never starts is a failing case, not an
error of hexhil: ``hexhil test`` runs the other cases, prints its table
with the reason and the firmware's last lines, writes JUnit with the case as an error,
keeps the trace with the reason on ``/expectations`` and exits 1; ``hexhil run`` exits 1
with the ending in its ``--json`` summary; the API's ``RunResult.ending`` says how the
firmware ended; ``hexhil margin`` goes on past a failing setting; the pytest plugin fails
the test (not errors) with the reason."""
from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hexhil.hil.run_result import Ending
from hexhil import Run
from hexhil.trace.reader import Trace
from conftest import ROOT, hexhil_in_process as hexhil

FLAT = ROOT / "scenarios" / "flat-tripod.toml"
BOARD_TRIPOD = ROOT / "examples" / "board_tripod.py"
START = "import time\ntime.sleep_ms(50)\n"
FIRMWARES = {
    "crash": START + "raise ValueError('boom')\n",
    # the board's own verdict: only polls for 2 virtual seconds
    "hang": START + "while True:\n    time.ticks_us()\n",
    "early": START + "print('bye')\n",
    "nostart": "this is not python\n",
}
CASE = '''[case]
name = "{name}"
scenario = "{flat}"
duration_s = 3
{firmware}
[[expect]]
name = "no firmware exception"
kind = "no_exception"
'''


def firmware(tmp_path: Path, kind: str) -> Path:
    p = tmp_path / f"{kind}.py"
    p.write_text(FIRMWARES[kind])
    return p


def test_hexhil_test_runs_every_case_and_judges_the_bad_firmwares(tmp_path: Path) -> None:
    files = []
    for name in ("good", *FIRMWARES):
        fw = "" if name == "good" else f'firmware = "{firmware(tmp_path, name)}"\n'
        p = tmp_path / f"{name}.toml"
        p.write_text(CASE.format(name=name, flat=FLAT, firmware=fw))
        files.append(str(p))
    junit, kept = tmp_path / "out.xml", tmp_path / "kept"
    r = hexhil("test", *files, "--quiet", "--python", "cpython-inprocess", "--junit", str(junit),
               "--keep-traces", str(kept))
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stderr and r.stderr == "", r.stderr
    lines = r.stdout.splitlines()
    rows = lines[2:lines.index(next(x for x in lines if "expectations passed" in x))]
    assert {row.split()[0] for row in rows} == {"good", *FIRMWARES}, r.stdout
    # the good case passed; every bad one fails on its ending; no_exception fails where
    # the firmware raised (not the early exit: it raised nothing)
    result = {(row.split()[0], "ending" if "firmware ending" in row else "exc"): row.split()[-1]
              for row in rows}
    assert result == {("good", "exc"): "pass", ("early", "exc"): "pass",
                      **{(n, "ending"): "FAIL" for n in FIRMWARES},
                      **{(n, "exc"): "FAIL" for n in ("crash", "hang", "nostart")}}, r.stdout
    for name, kind in (("crash", "crashed at t=0.05"), ("hang", "hung: no UART write"),
                       ("early", "exited at t=0.05"), ("nostart", "failed to start")):
        assert f"{name}: the firmware {name}.py {kind}" in r.stdout, r.stdout
    assert "ValueError: boom" in r.stdout   # the crash's last line
    # JUnit: every case, each bad one an error with its reason
    root = ET.parse(junit).getroot()
    suites = {s.get("name"): s for s in root.iter("testsuite")}
    assert set(suites) == {"good", *FIRMWARES}
    assert suites["good"].get("errors") == "0"
    for name in FIRMWARES:
        errors = [e for e in suites[name].iter("error")]
        assert len(errors) == 1 and f"{name}.py" in errors[0].get("message"), name
        props = {p.get("name"): p.get("value") for p in suites[name].iter("property")}
        assert props["firmware_ending"] != "completed"
    assert "ValueError: boom" in suites["crash"].find(".//error").text
    # the failing traces kept, the reason on /expectations
    for name in FIRMWARES:
        with Trace(kept / f"{name}.mcap") as t:
            notes = [v["message"] for _, v in t.decoded(["/expectations"])]
        assert any(f"{name}.py" in n for n in notes), (name, notes)


def test_hexhil_run_of_a_crashing_firmware_is_a_verdict_exit_1(tmp_path: Path) -> None:
    trace = tmp_path / "t.mcap"
    r = hexhil("run", str(FLAT), "--firmware", str(firmware(tmp_path, "crash")), "--out",
               str(trace), "--json")
    assert r.returncode == 1, r.stderr
    said = r.stderr.strip().splitlines()     # its traceback live, then the verdict
    assert said[-1] == \
        "hexhil: the firmware crash.py crashed at t=0.050000 s (exit 1): ValueError: boom"
    assert said[:-1] and all(ln.startswith("[  0.050000 s] ") for ln in said[:-1]), said
    s = json.loads(r.stdout.strip().splitlines()[-1])
    assert s["ending"]["kind"] == "crashed" and s["ending"]["t_s"] == 0.05
    assert s["ending"]["last_lines"][-1] == "ValueError: boom"
    with Trace(trace) as t:
        assert t.topics()


def test_what_a_micropython_firmware_prints_shows_live_after_its_virtual_time(
        tmp_path: Path) -> None:
    r = hexhil("run", str(FLAT), "--firmware", str(firmware(tmp_path, "early")), "--json")
    said = r.stderr.strip().splitlines()
    assert r.returncode == 1 and said[0] == "[  0.050000 s] bye", r.stderr   # at its print
    assert said[-1].startswith("hexhil: the firmware early.py exited at t=0.05"), r.stderr
    console = json.loads(r.stdout.strip().splitlines()[-1])["console"]
    assert console == [{"t_s": 0.05, "text": "bye"}], console
    quiet = hexhil("run", str(FLAT), "--firmware", str(firmware(tmp_path, "early")), "--quiet")
    assert quiet.stderr.strip().splitlines() == said[1:], quiet.stderr


@pytest.mark.parametrize("kind,ending", [
    ("crash", Ending.CRASHED), ("hang", Ending.HUNG), ("early", Ending.EXITED_EARLY),
    ("nostart", Ending.FAILED_TO_START)])
def test_the_api_says_how_the_firmware_ended(tmp_path: Path, kind: str, ending: Ending) -> None:
    with Run(FLAT, duration_s=3, firmware=firmware(tmp_path, kind)) as run:
        result = run.run()
    assert result.ending.kind is ending and not result.ending.completed
    assert result.ending.reason.startswith(f"the firmware {kind}.py")
    assert "\n" not in result.ending.reason


def test_the_api_says_a_good_firmware_completed() -> None:
    with Run(FLAT, duration_s=1, runtime="cpython-inprocess") as run:
        result = run.run()
    assert result.ending.kind is Ending.COMPLETED and result.ending.completed


def test_margin_goes_on_past_a_crashing_setting(tmp_path: Path) -> None:
    """A firmware that crashes at a setting (here: every setting) is the sweep's result."""
    from hexhil.expect import margin_sweep, spec

    p = tmp_path / "c.toml"
    p.write_text(CASE.format(name="c", flat=FLAT,
                             firmware=f'firmware = "{firmware(tmp_path, "crash")}"\n'))
    case = spec.load(p)
    m = margin_sweep.sweep(case, "cpython", axes={"return_delay_us": (0, 100)}, grid=((0,), (0,)))
    points = m.axes["return_delay_us"] + m.grid
    assert len(points) == 3 and all(not p.holds for p in points)
    assert all("firmware ending" in p.failed for p in points)
    assert "crashed" in points[0].measured[0]


def test_margin_firmware_runs_yours_in_place_of_the_cases(tmp_path: Path) -> None:
    """``hexhil margin --firmware``: the case names none, the sweep runs the one given (here
    a crashing one, so every point says so); a missing file is one line, exit 2."""
    from hexhil.expect import margin_sweep, spec

    p = tmp_path / "ours.toml"
    p.write_text(CASE.format(name="ours", flat=FLAT, firmware=""))
    case = spec.load(p)
    m = margin_sweep.sweep(case, "cpython", axes={"return_delay_us": (0,)}, grid=((0,), (0,)),
                           firmware=str(firmware(tmp_path, "crash")))
    points = m.axes["return_delay_us"] + m.grid
    assert len(points) == 2 and all("firmware ending" in p.failed for p in points)
    r = hexhil("margin", FLAT, "--expect", str(p), "--firmware", str(tmp_path / "nope.py"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--firmware" in r.stderr, r.stderr


PLUGIN_TEST = '''
def test_crash(hexhil_run):
    hexhil_run("{flat}", duration_s=2, firmware="{fw}")


def test_crash_allowed(hexhil_run):
    run = hexhil_run("{flat}", duration_s=2, firmware="{fw}", allow_failure=True)
    assert run.ending["kind"] == "crashed"
    run.check("no_exception")
'''


def test_the_pytest_plugin_fails_the_test_with_the_reason(tmp_path: Path) -> None:
    test = tmp_path / "test_mine.py"
    test.write_text(PLUGIN_TEST.format(flat=FLAT, fw=firmware(tmp_path, "crash")))
    r = subprocess.run([sys.executable, "-m", "pytest", str(test), "-p", "no:cacheprovider",
                        "-q"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "2 failed" in r.stdout and "error" not in r.stdout.splitlines()[-1], r.stdout
    assert "the firmware crash.py crashed at t=0.050000 s (exit 1): ValueError: boom" in r.stdout
    assert "no firmware exception" not in r.stdout   # check() named the kind itself
    assert "no_exception: measured 1 exceptions; limit 0 exceptions" in r.stdout, r.stdout
