"""What the run was is in the trace: every override (tactile, seed,
duration, firmware and its runtime, bus timing added) in the trace's metadata, the
``--json`` summary and the JUnit properties; ``scenario_of_trace`` gives what was run;
replay re-runs it; a flag that cannot apply is refused. And replay: a trace of a
firmware of the user's asks for it, and a divergence shows the servo packets decoded."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

from hexhil import scenario_of_trace
from hexhil.trace.reader import Trace
from conftest import ROOT, hexhil_in_process as hexhil

FLAT = str(ROOT / "scenarios" / "flat-tripod.toml")
EXAMPLE = ROOT / "examples" / "board_tripod.py"


def test_overrides_are_in_the_trace_the_summary_and_scenario_of_trace(tmp_path: Path) -> None:
    out = tmp_path / "t.mcap"
    r = hexhil("run", FLAT, "--duration", "1.5", "--seed", "7", "--no-tactile", "--python",
               "cpython-inprocess", "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout.strip().splitlines()[-1])
    assert s["tactile"] is False
    assert s["overrides"] == {"tactile": False, "seed": 7, "duration_s": 1.5,
                              "runtime": "cpython-inprocess"}
    with Trace(out) as t:
        meta = t.metadata()
    assert json.loads(meta["overrides"]) == s["overrides"]
    sc, seed = scenario_of_trace(meta, str(out))
    assert seed == 7 and sc.firmware.tactile is False and sc.scenario.duration_s == 1.5
    # replay re-runs it: the firmware sees the same (tactile off) settings, identically
    rep = hexhil("replay", str(out), "--python", "cpython")
    assert rep.returncode == 0 and rep.stdout.startswith("identical:"), rep.stdout


def test_the_summary_says_the_tactile_rule_as_run() -> None:
    r = hexhil("run", FLAT, "--duration", "0.5", "--python", "cpython-inprocess", "--json")
    s = json.loads(r.stdout.strip().splitlines()[-1])
    assert s["tactile"] is True and s["overrides"] == {"duration_s": 0.5,
                                                      "runtime": "cpython-inprocess"}


def test_a_firmware_run_records_its_path_and_runtime(tmp_path: Path) -> None:
    out = tmp_path / "b.mcap"
    r = hexhil("run", FLAT, "--duration", "1", "--firmware", str(EXAMPLE), "--out", str(out),
               "--json")
    s = json.loads(r.stdout.strip().splitlines()[-1])
    assert s["tactile"] is None
    assert s["overrides"]["firmware"] == str(EXAMPLE)
    assert s["overrides"]["firmware_runtime"] == "micropython-board"
    # replay without the firmware names what is missing, in one line
    rep = hexhil("replay", str(out))
    assert rep.returncode == 2 and rep.stderr.strip().splitlines() == [
        f"hexhil: {out} was recorded with --firmware ({EXAMPLE}), runtime micropython-board: "
        "give the same PATH to replay it"]


def test_a_flag_that_cannot_apply_is_refused(tmp_path: Path) -> None:
    r = hexhil("run", FLAT, "--no-tactile", "--firmware", str(EXAMPLE))
    assert r.returncode == 2 and "reads no such setting" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    case = tmp_path / "c.toml"
    case.write_text(f'[case]\nscenario = "{FLAT}"\n\n[[expect]]\nname = "n"\n'
                    'kind = "no_exception"\n')
    r = hexhil("test", str(case), "--no-tactile", "--firmware", str(EXAMPLE))
    assert r.returncode == 2 and "reads no such setting" in r.stderr
    case.write_text(f'[case]\nscenario = "{FLAT}"\ntactile = false\nfirmware = "{EXAMPLE}"\n'
                    '\n[[expect]]\nname = "n"\nkind = "no_exception"\n')
    r = hexhil("test", str(case))
    assert r.returncode == 2 and "'case.tactile'" in r.stderr


def test_junit_properties_and_kept_trace_say_no_tactile(tmp_path: Path) -> None:
    case = tmp_path / "c.toml"
    case.write_text(f'[case]\nscenario = "{FLAT}"\nduration_s = 1\n\n[[expect]]\n'
                    'name = "impossible"\nkind = "displacement"\ndx_m = [5, 6]\n')
    junit, kept = tmp_path / "o.xml", tmp_path / "kept"
    r = hexhil("test", str(case), "--quiet", "--no-tactile", "--python", "cpython-inprocess",
               "--junit", str(junit), "--keep-traces", str(kept))
    assert r.returncode == 1, r.stdout + r.stderr
    props = {p.get("name"): p.get("value") for p in ET.parse(junit).getroot().iter("property")}
    assert props["tactile"] == "False" and props["override.tactile"] == "False"
    assert props["override.seed"] == "1" and props["override.duration_s"] == "1.0"
    with Trace(kept / "c.mcap") as t:
        meta = t.metadata()
    assert json.loads(meta["overrides"])["tactile"] is False
    assert json.loads(meta["scenario_data"])["firmware"]["tactile"] is False


def test_a_divergence_shows_the_servo_packets_decoded(tmp_path: Path) -> None:
    trace = tmp_path / "t.mcap"
    assert hexhil("run", FLAT, "--firmware", str(EXAMPLE), "--duration", "2", "--out",
                  str(trace)).returncode == 0
    changed = tmp_path / "main.py"
    changed.write_text(EXAMPLE.read_text().replace("STEP, LIFT, PERIOD_S, CYCLE_MS = 0.05",
                                                   "STEP, LIFT, PERIOD_S, CYCLE_MS = 0.06"))
    diff = hexhil("replay", str(trace), "--firmware", str(changed), "--json")
    assert diff.returncode == 1
    d = json.loads(diff.stdout.strip().splitlines()[-1])["first_divergence"]
    want, got = d["packets"]["expected"], d["packets"]["actual"]   # the goals as written
    assert len(want) == len(got) == 1 and want != got, d
    assert all(p.startswith("SYNC_WRITE Goal Position ids 1-18 [1: ") for p in want + got), d
    text = hexhil("replay", str(trace), "--firmware", str(changed))
    assert "expected packets:" in text.stdout and "actual packets:" in text.stdout


def test_margin_settings_are_the_runs_overrides(tmp_path: Path) -> None:
    import dataclasses

    from hexhil.expect import case_runs, margin_sweep, spec

    case_file = tmp_path / "m.toml"
    case_file.write_text(f'[case]\nscenario = "{FLAT}"\nduration_s = 0.5\n\n[[expect]]\n'
                         'name = "n"\nkind = "no_exception"\n')
    job = margin_sweep._job(spec.load(case_file), "cpython-inprocess",
                      {"return_delay_us": 100, "bit_error_rate": 1e-4}, "m")
    r = case_runs.run_case(dataclasses.replace(job, keep_dir=str(tmp_path / "k"), keep_all=True))
    assert r.summary["overrides"]["return_delay_us"] == 100
    assert r.summary["overrides"]["faults.bit_error_rate"] == 1e-4
    with Trace(r.trace) as t:
        meta = t.metadata()
    assert json.loads(meta["overrides"])["return_delay_us"] == 100
    assert json.loads(meta["scenario_data"])["faults"]["bit_error_rate"] == 1e-4
