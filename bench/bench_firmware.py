"""Firmware compute per cycle (MicroPython and CPython on this host) and bus time per cycle
against the wire minimum of the transactions issued; real-time factor of the loop."""
from __future__ import annotations

from bench import Row
from hexhil import Run

DURATION_S = 10.0


def _scenario() -> dict:
    return {"gait": {"name": "tripod"}, "_path": "<bench>"}


def run() -> list[Row]:
    rows = []
    results = {}
    for python in ("micropython", "cpython"):
        r = Run(_scenario(), seed=1, runtime=python, duration_s=DURATION_S).run()
        results[python] = r
        rows.append(Row(f"firmware compute/cycle ({python}, mean)", r.firmware.compute_us_mean,
                        "us", "<= 200 us" if python == "micropython" else "",
                        f"max {r.firmware.compute_us_max} us over {r.cycles} cycles, 50 Hz tripod"))
    mp = results["micropython"]
    rows.append(Row("firmware compute micropython/cpython", mp.firmware.compute_us_mean
                    / results["cpython"].firmware.compute_us_mean, "ratio", "",
                    "same loop, same process run, host x86"))
    busy = mp.bus_busy_us / mp.loop_cycles
    wire = mp.bus_wire_us / mp.loop_cycles
    rows.append(Row("bus time/cycle", busy, "us", "",
                    "1 SYNC_WRITE (98 B) + 3 READs of 6 B, return delay 0"))
    rows.append(Row("bus time / wire minimum", busy / wire, "ratio", "<= 1.1", ""))
    rows.append(Row("loop real-time factor (no physics)", mp.sim_time_s / mp.wall_time_s, "x", "",
                    f"{DURATION_S:g} s simulated, micropython, {mp.round_trips} link round trips"))
    return rows
