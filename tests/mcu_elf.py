"""Builds the emulator's own test firmwares (tests/mcu/*.c) into STM32F411 ELFs and runs
them on the emulated board. A missing toolchain fails the test with the line to run."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from hil.scenario import load_scenario
from hil.link.served_firmware import served_firmware
from hil.run.lockstep import Simulator

ROOT = Path(__file__).resolve().parent.parent
MCU = ROOT / "tests" / "mcu"
APT_LINE = "apt-get install -y gcc-arm-none-eabi libnewlib-arm-none-eabi"
FLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-g",
         "-ffreestanding", "-nostdlib", "-Wall"]


def build(tmp_path: Path, source: str, *defines: str, script: Path | None = None,
          opt: str = "-O2") -> Path:
    """``tests/mcu/source`` with the test startup file, as ``tmp_path/<name>.elf``."""
    gcc = shutil.which("arm-none-eabi-gcc")
    if gcc is None:
        pytest.fail(f"arm-none-eabi-gcc is missing: {APT_LINE} (make does it as root)")
    out = tmp_path / (Path(source).stem + "".join(d.replace("=", "") for d in defines) + ".elf")
    cmd = [gcc, *FLAGS, opt, *(f"-D{d}" for d in defines), "-T", str(script or MCU / "f411.ld"),
           str(MCU / "startup.c"), str(MCU / source), "-o", str(out), "-lgcc"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return out


def run_elf(elf: Path, duration_s: float, switches=None, recorder=None, can_in=(),
            scenario: str = "scenarios/flat-tripod.toml"):
    """(result, simulator) of ``elf`` on the board, kinematic servos, switches from
    ``switches(t_us)`` and ``can_in`` frames sent by the host at the start."""
    sim = Simulator(load_scenario(ROOT / scenario), seed=0, switches=switches, recorder=recorder)
    for arb_id, data in can_in:
        sim.send_can(arb_id, data)
    return sim.run(duration_s, firmware=served_firmware(elf)), sim


def console(result) -> list[str]:
    """The last console lines (USART1 and semihosting) of a run."""
    return result.stderr_tail.splitlines()
