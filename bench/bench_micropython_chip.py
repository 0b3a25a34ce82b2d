"""MicroPython's stm32 port on the emulated STM32F411 (../shared/firmware/micropython, the
empty-filesystem ELF with a main.py laid into /flash): the real-time factor of a 50 Hz
control loop that is busy about a fifth of its period in chip cycles (``LOOP``: inverse
kinematics for six legs in floats, a 62-byte SYNC_WRITE and a ping a cycle), 3 s of
flat-tripod, without and with a trace, median of ``REPEATS``; then our own firmware/main.py
laid the same way (``--main firmware/main.py``: it is busy most of its period). CPU time
counts this process."""
from __future__ import annotations

import os
import resource
import statistics
import tempfile
from pathlib import Path

from bench import Row
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil import Run

ROOT = Path(__file__).resolve().parent.parent
ELF = ROOT.parent / "shared" / "firmware" / "micropython" / "micropython-hexhil-f411.elf"
DURATION_S = 3.0
REPEATS = 3
LOOP = """\
import math
import time
from machine import Pin, UART

d = Pin("A1", Pin.OUT, value=0)
u = UART(2, baudrate=1000000, timeout=10, timeout_char=2)
PING = bytes((0xFF, 0xFF, 1, 2, 1, 0xFB))
COXA, FEMUR, TIBIA = 0.05, 0.08, 0.12
ROUNDS = 3


def leg(x, y, z):
    a = math.atan2(y, x)
    r = math.sqrt(x * x + y * y) - COXA
    d2 = r * r + z * z
    k = (d2 - FEMUR * FEMUR - TIBIA * TIBIA) / (2 * FEMUR * TIBIA)
    k = max(-1.0, min(1.0, k))
    t = math.acos(k)
    f = math.atan2(z, r) + math.atan2(TIBIA * math.sin(t), FEMUR + TIBIA * math.cos(t))
    return a, f, t


def packet(angles):
    body = bytearray((0xFE, 4 + 3 * 18, 0x83, 0x1E, 2))
    for i, rad in enumerate(angles):
        p = max(0, min(1023, int(512 + rad * 195.0)))
        body += bytes((i + 1, p & 0xFF, p >> 8))
    return b"\\xff\\xff" + body + bytes((~sum(body) & 0xFF,))


t = time.ticks_ms()
n = 0
while True:
    phase = n * 0.1
    angles = []
    for rep in range(ROUNDS):
        angles = []
        for i in range(6):
            angles.extend(leg(0.15 + 0.02 * math.cos(phase + i), 0.02 * math.sin(phase + i),
                              -0.08 + 0.01 * rep))
    d.value(1)
    u.write(packet(angles))
    u.write(PING)
    while not u.txdone():
        pass
    d.value(0)
    u.read(6)
    n += 1
    t = time.ticks_add(t, 20)
    time.sleep_ms(max(0, time.ticks_diff(t, time.ticks_ms())))
"""


def _cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    return own.ru_utime + own.ru_stime


def _row(name: str, main: Path, traced: bool, tmp: str, target: str) -> Row:
    factors, cpu_factors = [], []
    for i in range(REPEATS):
        trace = Path(tmp) / f"run{i}.mcap" if traced else None
        c0 = _cpu_s()
        result = Run("scenarios/flat-tripod.toml", seed=1, duration_s=DURATION_S,
                     firmware=ELF, flash_files=FlashFiles(main=main), trace=trace).run()
        cpu_factors.append(result.sim_time_s / (_cpu_s() - c0))
        factors.append(result.sim_time_s / result.wall_time_s)
    mcu = result.firmware.other.get("mcu", {})
    busy = mcu.get("deadline", {}).get("busy_p50_ms", 0.0)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    return Row(name, statistics.median(factors), "x", target,
               f"{DURATION_S:g} s flat-tripod, median of {REPEATS} "
               f"({min(factors):.2f}-{max(factors):.2f}); by CPU time "
               f"{statistics.median(cpu_factors):.2f}x; busy p50 {busy:.2f} ms of 20; "
               f"{mcu.get('instructions', 0):,} instructions, "
               f"{mcu.get('link_requests', 0):,} link requests; load {load}")


def run() -> list[Row]:
    if not ELF.is_file():
        raise FileNotFoundError(f"{ELF}: the shared firmware folder must sit beside the "
                                "repository")
    with tempfile.TemporaryDirectory() as tmp:
        main = Path(tmp) / "main.py"
        main.write_text(LOOP)
        return [_row("MicroPython 50 Hz loop on the chip", main, False, tmp, ">= 2"),
                _row("MicroPython 50 Hz loop on the chip, recording a trace", main, True,
                     tmp, ">= 1"),
                _row("our firmware/main.py on the chip", ROOT / "firmware" / "main.py",
                     False, tmp, ">= 2")]
