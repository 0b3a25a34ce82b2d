"""The firmware STM32 teams ship (../shared/firmware: ST's HAL in a CubeMX layout, and
FreeRTOS on it) on the emulated board, as ``hexhil run`` runs them: the real-time factor of
3 s of flat-tripod, median of ``REPEATS`` alternating runs, beside the same figure for the
C tripod built for the host (the baseline, measured in the same bench run)."""
from __future__ import annotations

import statistics
import tempfile
from pathlib import Path

from bench import Row
from host_tools import Run
from host_tools.c_sdk import build

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "firmware"
ELFS = {"cube.elf": SHARED / "cube" / "cube.elf",
        "freertos.elf": SHARED / "freertos" / "freertos.elf"}
DURATION_S = 3.0
REPEATS = 3


def _factor(firmware: Path) -> float:
    result = Run("scenarios/flat-tripod.toml", seed=1, duration_s=DURATION_S,
                 firmware=str(firmware)).run()
    return result.sim_time_s / result.wall_time_s


def run() -> list[Row]:
    missing = [str(p) for p in ELFS.values() if not p.is_file()]
    if missing:
        raise FileNotFoundError(f"{missing[0]}: the shared firmware folder must sit beside "
                                "the repository")
    factors: dict[str, list[float]] = {name: [] for name in (*ELFS, "host")}
    with tempfile.TemporaryDirectory() as tmp:
        host = Path(tmp) / "c_tripod"
        build([str(ROOT / "examples" / "c_tripod" / "main.c")], host)
        for _ in range(REPEATS):
            for name, path in ELFS.items():
                factors[name].append(_factor(path))
            factors["host"].append(_factor(host))
    base = statistics.median(factors["host"])
    return [Row(f"{name} real-time factor", statistics.median(f), "x", ">= 5",
                f"{DURATION_S:g} s flat-tripod, median of {REPEATS} "
                f"({min(f):.2f}-{max(f):.2f}); "
                f"the C tripod host build beside it: {base:.1f}x")
            for name, f in factors.items() if name != "host"]
