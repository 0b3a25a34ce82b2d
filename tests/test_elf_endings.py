"""A firmware's end on the emulated board is the verdict the same source gets on the host
(hil/mcu/verdicts.py): exit(3) through newlib's `_exit`, abort(), a failed assert (its
message on the console), a return from main and CubeMX's Error_Handler (interrupts masked,
an endless loop) end the run as crashed, exited or hung, naming what, exit 1; `hexhil run`
exits 1 and `hexhil test` counts the case as failed. tests/elf_firmware/endings.c, built
with newlib-nano as a CubeMX project is."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from hexhil.hil.link.served_firmware import served_firmware
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run_result import Ending
from hexhil.hil.scenario import load_scenario
from hexhil import c_sdk
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil_in_process

FLAT = ROOT / "scenarios" / "flat-tripod.toml"
SOURCE = ROOT / "tests" / "elf_firmware" / "endings.c"


@pytest.fixture(scope="module")
def ending_elf(tmp_path_factory):
    out = tmp_path_factory.mktemp("endings")

    def build(end: str, *defines: str) -> Path:
        name = "_".join((end, *defines)).replace("=", "")
        return c_sdk.build([str(SOURCE)], out / f"{name}.elf",
                           (f"-DEND=END_{end}", *(f"-D{d}" for d in defines)), "stm32f411")
    return build


def run(elf: Path, duration_s: float = 0.1, **kw):
    sim = Simulator(load_scenario(FLAT), seed=0)
    return sim.run(duration_s, firmware=served_firmware(elf, **kw))


@pytest.mark.parametrize("end, kind, says, code", [
    ("EXIT", Ending.CRASHED, "exited with status 3 through _exit (from exit)", 3),
    ("ABORT", Ending.CRASHED, "called abort() (from main)", 1),
    ("RETURN", Ending.CRASHED, "returned 3 from main", 3),
])
def test_an_exit_an_abort_and_a_return_from_main_crash_the_run_naming_it(
        ending_elf, end, kind, says, code):
    result = run(ending_elf(end))
    ending = result.ending
    assert ending.kind is kind and result.exit_code == 1, ending
    assert ending.reason.startswith(f"the firmware {end}.elf {says} at t=0.02"), ending
    assert ending.exit_code == code and ending.last_lines == ("endings: start",)
    assert 0.02 < ending.t_s < 0.03


def test_exit_0_and_main_returning_0_are_an_early_exit(ending_elf):
    for end, says in (("EXIT", "exited through _exit(0) (from exit) before the run's end"),
                      ("RETURN", "returned 0 from main before the run's end")):
        result = run(ending_elf(end, "EXIT_STATUS=0"))
        assert result.ending.kind is Ending.EXITED_EARLY and result.exit_code == 1
        assert says in result.ending.reason, result.ending


def test_a_failed_assert_prints_newlibs_message_and_names_the_assertion(ending_elf):
    result = run(ending_elf("ASSERT"))
    ending = result.ending
    assert ending.kind is Ending.CRASHED and result.exit_code == 1, ending
    line = next(i for i, text in enumerate(SOURCE.read_text().splitlines(), 1)
                if "assert(servos_found" in text)
    assert f"failed an assertion: assert(servos_found == 18) in main at {SOURCE}:{line} " \
        in ending.reason, ending.reason
    assert ending.last_lines[-1] == (f'assertion "servos_found == 18" failed: file "{SOURCE}", '
                                     f'line {line}, function: main'), ending.last_lines


def test_error_handler_spinning_with_interrupts_masked_is_hung_after_the_limit(ending_elf):
    elf = ending_elf("ERROR_HANDLER")
    result = run(elf, 0.3, masked_limit_s=0.05)
    ending = result.ending
    assert ending.kind is Ending.HUNG and result.exit_code == 1, ending
    assert "hung: it ran with interrupts masked (PRIMASK) for 0.05 s" in ending.reason
    assert "in Error_Handler" in ending.reason, ending.reason
    assert 0.07 <= ending.t_s <= 0.09, ending          # 20 ms of start, then the limit
    assert run(elf, 0.3, masked_limit_s=0.5).ending.completed   # within its limit: runs on
    ending = run(ending_elf("RTOS_ASSERT"), 0.3, masked_limit_s=0.05).ending
    assert ending.kind is Ending.HUNG and "masked (BASEPRI) for 0.05 s" in ending.reason \
        and "in main" in ending.reason, ending


def test_a_handler_spinning_below_systick_is_hung_and_the_limit_is_checked(ending_elf):
    result = run(ending_elf("HANDLER_LOOP"), 0.3, masked_limit_s=0.05)
    ending = result.ending              # SysTick still preempts it: no lockup, a hang
    assert ending.kind is Ending.HUNG and result.exit_code == 1, ending
    assert "hung: Default_Handler (interrupt 29) ran a loop that branches to itself for " \
        "0.05 s" in ending.reason, ending.reason
    assert 0.07 <= ending.t_s <= 0.09, ending
    with pytest.raises(UserError, match="masked_limit_s 0: give a time above 0 s"):
        served_firmware(ending_elf("NONE"), masked_limit_s=0)


def test_hal_delay_in_an_interrupt_systick_cannot_preempt_is_hung(ending_elf):
    ending = run(ending_elf("ISR_DELAY"), 0.3, masked_limit_s=0.05).ending
    assert ending.kind is Ending.HUNG, ending      # on the chip the tick never comes
    assert "hung: interrupt 29's handler ran 0.05 s with SysTick pending behind it, never " \
        "taken" in ending.reason and " in HAL_" in ending.reason, ending.reason
    assert 0.07 <= ending.t_s <= 0.09, ending


def test_a_firmware_idling_in_wfi_completes_and_its_console_shows_live(ending_elf):
    result = run(ending_elf("NONE"))
    assert result.ending.completed and result.exit_code == 0, result.ending
    assert [text for _, text in result.console] == ["endings: start"]  # kept on success
    proc = hexhil_in_process("run", FLAT, "--duration", "0.1", "--firmware", ending_elf("NONE"))
    assert proc.returncode == 0, proc.stderr
    printed = re.fullmatch(r"\[ *(\d+\.\d{6}) s\] endings: start", proc.stderr.strip())
    assert printed and 0 < float(printed[1]) < 0.01, proc.stderr   # its virtual time


def test_hexhil_run_exits_1_and_hexhil_test_fails_the_case(ending_elf, tmp_path):
    elf = ending_elf("ASSERT")
    proc = hexhil_in_process("run", FLAT, "--duration", "0.1", "--firmware", elf, "--quiet",
                             "--json")
    said = proc.stderr.splitlines()
    assert proc.returncode == 1 and len(said) == 1 and \
        "failed an assertion: assert(servos_found == 18)" in said[0], proc.stderr
    console = json.loads(proc.stdout.splitlines()[-1])["console"]
    assert [c["text"] for c in console][0] == "endings: start"
    assert 0.0 < console[0]["t_s"] < console[1]["t_s"] < 0.05, console
    assert console[1]["text"].startswith('assertion "servos_found == 18" failed')
    case = tmp_path / "short.toml"
    case.write_text(f'[case]\nscenario = "{FLAT}"\nduration_s = 0.1\n\n[[expect]]\n'
                    'name = "no firmware exception"\nkind = "no_exception"\n')
    proc = hexhil_in_process("test", case, "--firmware", elf)
    assert proc.returncode == 1 and "FAIL" in proc.stdout and "assert" in proc.stdout, \
        proc.stdout + proc.stderr
