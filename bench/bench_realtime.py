"""The real-time rig (``hexhil bus --world``) with our firmware on its serial HAL, 30 s of
flat-tripod: the distance walked beside the lockstep run's, and the pacing report."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from bench import Row

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = "scenarios/flat-tripod.toml"
DURATION_S = 30
# firmware_settings(flat-tripod): what hexhil run hands the firmware at boot
CONFIG = {"gait": "tripod", "step_length_m": 0.05, "step_height_m": 0.03, "period_s": 2.778,
          "cycle_hz": 50.0}


def _lockstep_dx_m() -> float:
    out = subprocess.run([sys.executable, "-m", "hexhil.cli", "run", SCENARIO, "--json"],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])["body"]["dx_m"]


def realtime() -> dict:
    rig = subprocess.Popen([sys.executable, "-m", "hexhil.cli", "bus", "--world", SCENARIO,
                            "--duration", str(DURATION_S + 2), "--json"], cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pty = rig.stdout.readline().strip().split(": ", 1)[1]
    env = dict(os.environ, MICROPYPATH=f"{ROOT}:.frozen")
    subprocess.run([str(Path(sys.executable).with_name("micropython")), "firmware/main.py",
                    "--serial", pty, "--config", json.dumps(CONFIG)], cwd=ROOT, env=env,
                   capture_output=True, timeout=DURATION_S + 60)
    out, _ = rig.communicate(timeout=60)
    return json.loads(out.strip().splitlines()[-1])


def run() -> list[Row]:
    s = realtime()
    lock = _lockstep_dx_m()
    p = s["pacing"]
    load = os.getloadavg()[0]
    return [Row("real-time flat-tripod, our firmware: body dx", s["body"]["dx_m"], "m",
                f"within 10 % of lockstep {lock:.3f} m", f"load {load:.1f}"),
            Row("real-time pacing: p99 lag", p["p99_lag_ms"], "ms", "< 20 (one control period)"),
            Row("real-time pacing: max lag", p["max_lag_ms"], "ms", "", f"{p['late_steps']} late "
                f"of {p['advances']} advances"),
            Row("real-time master violations (our firmware)", s["violations"]["total"], "", "0")]
