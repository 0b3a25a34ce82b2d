"""The C tripod as an STM32F411 ELF on the emulated board (hil/mcu/, issue 40) against the
same ``examples/c_tripod/main.c`` built for the host, measured in one run."""
from __future__ import annotations

import tempfile
from pathlib import Path

from bench import Row
from host_tools import Run
from host_tools.c_sdk import build

DURATION_S = 10.0
MAIN = Path(__file__).resolve().parent.parent / "examples" / "c_tripod" / "main.c"


def run() -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        host, elf = Path(tmp) / "c_tripod", Path(tmp) / "c_tripod.elf"
        build([str(MAIN)], host)
        build([str(MAIN)], elf, target="stm32f411")
        results = {k: Run("scenarios/flat-tripod.toml", seed=1, duration_s=DURATION_S,
                          firmware=fw).run() for k, fw in (("host", host), ("elf", elf))}
    h, e = results["host"], results["elf"]
    mcu = e.firmware.get("mcu", {})
    return [
        Row("c_tripod ELF speed / host build", h.wall_time_s / e.wall_time_s, "ratio", ">= 0.5",
            f"{DURATION_S:g} s flat-tripod: host build {h.wall_time_s:.2f} s, ELF "
            f"{e.wall_time_s:.2f} s of wall time"),
        Row("c_tripod ELF real-time factor", e.sim_time_s / e.wall_time_s, "x", ">= 5",
            f"{mcu.get('instructions', 0):,} instructions run, "
            f"{mcu.get('skipped_cycles', 0):,} cycles of waiting skipped, "
            f"{mcu.get('link_requests', 0):,} link requests"),
    ]
