"""Builds the emulator's own test firmwares (tests/mcu/*.c, each with tests/mcu/startup.c:
its vector table and reset) into STM32F411 ELFs the way a user builds a bare-metal one
(``hexhil sdk build --bare``: the SDK's linker script, no HAL, no libc) and runs them on the
emulated board. A missing toolchain fails the test with the line to run."""
from __future__ import annotations

from pathlib import Path

from hexhil.hil.scenario import load_scenario
from hexhil.hil.link.served_firmware import served_firmware
from hexhil.hil.run.lockstep import Simulator
from hexhil import c_sdk

ROOT = Path(__file__).resolve().parent.parent
MCU = ROOT / "tests" / "mcu"


def build(tmp_path: Path, source: str, *defines: str, opt: str = "-O2",
          extra: tuple[str, ...] = (), cflags: tuple[str, ...] = ()) -> Path:
    """``tests/mcu/source`` with the test startup file (and ``extra`` sources), as
    ``tmp_path/<name>.elf``."""
    out = tmp_path / (Path(source).stem + "".join(d.replace("=", "") for d in defines) + ".elf")
    return c_sdk.build([str(MCU / "startup.c"), str(MCU / source), *extra], out,
                       (opt, *(f"-D{d}" for d in defines), *cflags), "stm32f411", bare=True)


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
