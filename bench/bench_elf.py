"""The C tripod as an STM32F411 ELF on the emulated board (hil/mcu/) against the
same ``examples/c_tripod/main.c`` built for the host, measured in one run: the two builds
alternate ``REPEATS`` times and each row is the median, since the machine is shared (the
load average is in the note). CPU time counts this process and the host build's child."""
from __future__ import annotations

import os
import resource
import statistics
import tempfile
from pathlib import Path

from bench import Row
from hexhil import Run
from hexhil.c_sdk import build

DURATION_S = 10.0
REPEATS = 3
MAIN = Path(__file__).resolve().parent.parent / "examples" / "c_tripod" / "main.c"


def _cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def run() -> list[Row]:
    wall: dict[str, list[float]] = {"host": [], "elf": []}
    cpu: dict[str, list[float]] = {"host": [], "elf": []}
    with tempfile.TemporaryDirectory() as tmp:
        fws = {"host": Path(tmp) / "c_tripod", "elf": Path(tmp) / "c_tripod.elf"}
        build([str(MAIN)], fws["host"])
        build([str(MAIN)], fws["elf"], target="stm32f411")
        for _ in range(REPEATS):
            for kind, fw in fws.items():
                c0 = _cpu_s()
                result = Run("scenarios/flat-tripod.toml", seed=1, duration_s=DURATION_S,
                             firmware=fw).run()
                cpu[kind].append(_cpu_s() - c0)
                wall[kind].append(result.wall_time_s)
                if kind == "elf":
                    elf = result
    h, e = statistics.median(wall["host"]), statistics.median(wall["elf"])
    hc, ec = statistics.median(cpu["host"]), statistics.median(cpu["elf"])
    mcu = elf.firmware.other.get("mcu", {})
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    return [
        Row("c_tripod ELF speed / host build", h / e, "ratio", ">= 0.5",
            f"{DURATION_S:g} s flat-tripod, median of {REPEATS}: host build {h:.2f} s, ELF "
            f"{e:.2f} s of wall time; CPU {hc:.2f} s vs {ec:.2f} s ({hc / ec:.2f}); "
            f"load {load}"),
        Row("c_tripod ELF real-time factor", elf.sim_time_s / e, "x", ">= 5",
            f"{mcu.get('instructions', 0):,} instructions run, "
            f"{mcu.get('skipped_cycles', 0):,} cycles of waiting skipped, "
            f"{mcu.get('link_requests', 0):,} link requests"),
    ]
