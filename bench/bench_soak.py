"""The soak: ``scenarios/soak.toml``, ten simulated minutes on a faulty bus and a
lossy CAN bus; the firmware keeps its rate, counts every fault, rides through what it can
and stops safely for the rest. Rows: cycles, overruns, faults by kind, wall time."""
from __future__ import annotations

from pathlib import Path

from bench import Row
from hexhil import run_summary as run_mod

SOAK = Path(__file__).resolve().parent.parent / "scenarios" / "soak.toml"


def run() -> list[Row]:
    s, result = run_mod.run(str(SOAK))
    rate = s["cycles"] / s["sim_time_s"] if s["sim_time_s"] else 0.0
    rows = [
        Row("soak: simulated time", s["sim_time_s"], "s", "600 s", "scenarios/soak.toml"),
        Row("soak: cycles", s["cycles"], "cycles", "", f"{rate:.1f} Hz kept"),
        Row("soak: overruns", s["overruns"], "cycles", "0", ""),
        Row("soak: unhandled exceptions", s["unhandled_exceptions"], "", "0", ""),
        Row("soak: wall time", s["wall_time_s"], "s", "", f"{s['real_time_factor']}x real time"),
    ]
    for kind, n in s["faults"].items():
        rows.append(Row(f"soak: fault {kind}", n, "events", "", ""))
    rows.append(Row("soak: stopped safely", float(s["stopped_safely"]), "bool", "1",
                    f"state {s['state']}: {s['stop_reason']}"))
    return rows
