"""The firmware STM32 teams ship (../shared/firmware: ST's HAL in a CubeMX layout, and
FreeRTOS on it) on the emulated board, as ``hexhil run`` runs them: the real-time factor of
3 s of flat-tripod, median of ``REPEATS`` alternating runs, beside the same figure for the
C tripod built for the host (the baseline, measured in the same bench run). The note gives the
factor by CPU time too (this process's), since the machine is shared."""
from __future__ import annotations

import resource
import statistics
import tempfile
from pathlib import Path

from bench import Row
from hexhil import Run
from hexhil.c_sdk import build

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "firmware"
ELFS = {"cube.elf": SHARED / "cube" / "cube.elf",
        "freertos.elf": SHARED / "freertos" / "freertos.elf"}
DURATION_S = 3.0
REPEATS = 3


def _cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    return own.ru_utime + own.ru_stime


def _factor(firmware: Path, cpu: list[float]) -> float:
    """The run's real-time factor by wall time; by CPU time appended to ``cpu``."""
    c0 = _cpu_s()
    result = Run("scenarios/flat-tripod.toml", seed=1, duration_s=DURATION_S,
                 firmware=str(firmware)).run()
    cpu.append(result.sim_time_s / (_cpu_s() - c0))
    return result.sim_time_s / result.wall_time_s


def run() -> list[Row]:
    missing = [str(p) for p in ELFS.values() if not p.is_file()]
    if missing:
        raise FileNotFoundError(f"{missing[0]}: the shared firmware folder must sit beside "
                                "the repository")
    factors: dict[str, list[float]] = {name: [] for name in (*ELFS, "host")}
    cpu: dict[str, list[float]] = {name: [] for name in ELFS}   # the host build: a child
    with tempfile.TemporaryDirectory() as tmp:
        host = Path(tmp) / "c_tripod"
        build([str(ROOT / "examples" / "c_tripod" / "main.c")], host)
        for _ in range(REPEATS):
            for name, path in ELFS.items():
                factors[name].append(_factor(path, cpu[name]))
            factors["host"].append(_factor(host, []))
    base = statistics.median(factors["host"])
    return [Row(f"{name} real-time factor", statistics.median(f), "x", ">= 5",
                f"{DURATION_S:g} s flat-tripod, median of {REPEATS} "
                f"({min(f):.2f}-{max(f):.2f}), by CPU time {statistics.median(cpu[name]):.2f}x; "
                f"the C tripod host build beside it: {base:.1f}x")
            for name, f in factors.items() if name != "host"]
