"""``hexhil test`` on a firmware that is not ours (``--firmware``, ``[case] firmware``) and on
a run recorded elsewhere (``--trace``: a real board through ``hexhil bus --world``)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hexhil.expect import spec
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil_in_process as hexhil

BOARD_TRIPOD = ROOT / "examples" / "board_tripod.py"
FLAT = ROOT / "scenarios" / "flat-tripod.toml"
HEAD = f'[case]\nscenario = "{FLAT}"\nduration_s = 8\n'
# what examples/board_tripod.py does (it sends no CAN heartbeat: that stays ours)
CLEAN = '''
[[expect]]
name = "no protocol violations"
kind = "protocol"

[[expect]]
name = "no firmware exception"
kind = "no_exception"
'''
WALKS = '''
[[expect]]
name = "walks ahead"
kind = "displacement"
window_s = [2, 8]
dx_m = [0.15, 0.6]
''' + CLEAN
HEARTBEAT = '''
[[expect]]
name = "heartbeat"
kind = "can"
message = "heartbeat"
window_s = [1, 8]
rate_hz = [9, 11]
'''


def case_file(tmp_path: Path, text: str, name: str = "mine.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_a_board_firmware_is_tested_with_the_same_expectations(tmp_path: Path) -> None:
    case = case_file(tmp_path, HEAD + WALKS + HEARTBEAT)
    junit = tmp_path / "j.xml"
    proc = hexhil("test", str(case), "--firmware", str(BOARD_TRIPOD), "--junit", str(junit),
                  "--quiet")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    rows = {line.split("  ")[1].strip(): line.rstrip() for line in proc.stdout.splitlines()
            if line.startswith("mine ")}
    assert rows["walks ahead"].endswith("pass") and rows["no protocol violations"].endswith(
        "pass") and rows["no firmware exception"].endswith("pass"), proc.stdout
    assert rows["heartbeat"].endswith("FAIL") and "0 frames" in rows["heartbeat"]
    failures = ET.parse(junit).getroot().findall(".//testcase/failure")
    assert [f.get("type") for f in failures] == ["can"]


def test_a_case_names_its_firmware_beside_the_file(tmp_path: Path) -> None:
    (tmp_path / "fw").mkdir()
    (tmp_path / "fw" / "main.py").write_text(BOARD_TRIPOD.read_text())
    case = case_file(tmp_path, HEAD + 'firmware = "fw/main.py"\n' + WALKS)
    assert spec.load(case).firmware == str(tmp_path / "fw" / "main.py")
    proc = hexhil("test", str(case), "--quiet")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "3 of 3 expectations passed" in proc.stdout


@pytest.mark.parametrize("extra, says", [
    ('firmware = "missing.py"\n', "key 'case.firmware'"),
    ('firmware = "fw.py"\npython = "cpython"\n', "leave out 'case.python'"),
])
def test_a_bad_case_firmware_is_one_line(tmp_path: Path, extra: str, says: str) -> None:
    (tmp_path / "fw.py").write_text("pass\n")
    case = case_file(tmp_path, HEAD + extra + WALKS)
    with pytest.raises(UserError) as info:
        spec.load(case)
    assert says in str(info.value) and str(case) in str(info.value)


@pytest.mark.parametrize("argv, says", [
    (["--firmware", "nowhere.py"], "--firmware nowhere.py: not a file"),
    (["--firmware", str(BOARD_TRIPOD), "--python", "cpython"], "leave out --runtime"),
    (["--trace", "t.mcap", "--repeat", "2"], "--trace evaluates one recorded run"),
])
def test_bad_options_are_one_line(tmp_path: Path, argv: list[str], says: str) -> None:
    case = case_file(tmp_path, HEAD + WALKS)
    proc = hexhil("test", str(case), *argv)
    assert proc.returncode == 2 and proc.stdout == "" and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and says in proc.stderr, proc.stderr


def test_a_recorded_run_is_judged_as_the_run_itself(tmp_path: Path) -> None:
    """--trace on the trace of a run gives that run's table, row for row."""
    case = case_file(tmp_path, HEAD + WALKS)
    ran = hexhil("test", str(case), "--python", "cpython-inprocess", "--quiet")
    trace = tmp_path / "run.mcap"
    rec = hexhil("run", str(FLAT), "--duration", "8", "--python", "cpython-inprocess",
                 "--out", str(trace), "--json")
    assert rec.returncode == 0, rec.stderr
    judged = hexhil("test", str(case), "--trace", str(trace))
    assert judged.returncode == ran.returncode == 0, judged.stdout + judged.stderr
    assert judged.stdout == ran.stdout


def test_a_real_time_board_run_is_judged_from_its_trace(tmp_path: Path) -> None:
    """The real-board flow: `hexhil bus --world ... --out`, then `hexhil test --trace`. Our
    firmware on its serial back end plays the board, on the rig's pty."""
    trace = tmp_path / "rt.mcap"
    rig = subprocess.Popen([sys.executable, "-m", "hexhil.cli", "bus", "--world", str(FLAT),
                            "--duration", "6", "--out", str(trace), "--json"], cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pty = rig.stdout.readline().strip().split(": ", 1)[1]
    env = dict(os.environ, MICROPYPATH=f"{ROOT}:.frozen")
    subprocess.run([str(Path(sys.executable).with_name("micropython")), "firmware/main.py",
                    "--serial", pty], cwd=ROOT, env=env, capture_output=True, timeout=60)
    out, err = rig.communicate(timeout=60)
    assert rig.returncode == 0, err
    served_s = json.loads(out.strip().splitlines()[-1])["served_s"]
    case = case_file(tmp_path, f'[case]\nscenario = "{FLAT}"\n' + '''
[[expect]]
name = "moves ahead"
kind = "displacement"
dx_m = [0.01, 0.5]
''' + CLEAN + HEARTBEAT)
    proc = hexhil("test", str(case), "--trace", str(trace), "--keep-traces",
                  str(tmp_path / "kept"))
    rows = [line for line in proc.stdout.splitlines() if line.startswith("mine ")]
    # the board's own reports and CAN frames travel on no line the rig sees: FAIL, said so
    assert [r.rstrip().endswith("pass") for r in rows] == [True, True, False, False], \
        proc.stdout
    assert "not seen: no firmware link" in rows[2] and "0 frames" in rows[3]
    assert proc.returncode == 1 and served_s > 1.0
    assert (tmp_path / "kept" / "mine.mcap").is_file()
