"""A firmware's own fault handlers run as on the chip (hil/mcu/faults.py): the fault taken
as its exception with CFSR, HFSR and BFAR set and the faulting PC stacked, escalated to
HardFault unless SHCSR enables it; a handler that spins ends the run crashed naming the
fault and the handler; one that resets the MCU reboots it and the run goes on."""
import re

import pytest

from hexhil.hil.link.served_firmware import served_firmware
from hexhil.hil.mcu.elf_image import load_elf
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run_result import Ending
from hexhil.hil.scenario import load_scenario
from mcu_elf import build, console
from conftest import ROOT


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """HANDLER -> (result, the ELF's symbols) of tests/mcu/fault_handler.c, 0.1 s each."""
    out = {}
    tmp = tmp_path_factory.mktemp("faults")
    for handler in (1, 2, 3, 4):
        elf = build(tmp, "fault_handler.c", f"HANDLER={handler}")
        sim = Simulator(load_scenario(ROOT / "scenarios" / "flat-tripod.toml"), seed=0)
        out[handler] = (sim.run(0.1, firmware=served_firmware(elf, masked_limit_s=0.02)),
                        load_elf(elf).symbols)
    return out


def test_hardfault_handler_sees_the_stacked_pc_and_status_then_its_spin_ends_the_run(runs):
    result, symbols = runs[1]
    explode = symbols["explode"] & ~1
    assert console(result)[1:] == [f"pc {explode:08x}", "cfsr 00010000", "hfsr 40000000"]
    ending = result.ending
    assert ending.kind is Ending.CRASHED and ending.exit_code == 1
    assert f"an undefined instruction (UsageFault) at PC 0x{explode:08x} in explode" in \
        ending.reason
    assert "took HardFault (UNDEFINSTR, escalated: HFSR FORCED)" in ending.reason
    assert "its handler HardFault_Handler then spun in a loop" in ending.reason


def test_an_enabled_usagefault_runs_its_own_handler_bounded_in_virtual_time(runs):
    result, _ = runs[2]
    assert console(result)[1:] == ["usage cfsr 00010000"]
    ending = result.ending
    assert ending.kind is Ending.CRASHED and "took UsageFault (UNDEFINSTR)" in ending.reason
    assert "UsageFault_Handler was still running after 0.02" in ending.reason
    assert 0.02 <= ending.t_s < 0.03


def test_a_busfault_handler_that_resets_reboots_the_mcu_and_the_run_goes_on(runs):
    result, _ = runs[3]
    assert console(result) == ["boot 000b0075", "bus cfsr 00008200", "bfar 60000004",
                               "boot 000b0076"]        # PRECISERR | BFARVALID, the address
    assert result.ending.kind is Ending.COMPLETED
    mcu = result.firmware.other["mcu"]
    assert mcu["resets"] == 1 and mcu["reset_causes"] == {"SYSRESETREQ": 1}
    assert len(mcu["faults"]) == 1 and mcu["faults"][0].startswith("a read of nothing at PC")


def test_a_write_to_nothing_is_imprecise_its_stacked_pc_after_the_store(runs):
    result, symbols = runs[4]
    lines = console(result)
    assert lines[2:] == ["cfsr 00000400", "hfsr 40000000"]        # IMPRECISERR, no BFAR
    at = re.search(r"a write to nothing at PC 0x([0-9a-f]{8}) in store_nowhere",
                   result.ending.reason)
    assert at, result.ending.reason
    assert int(lines[1].split()[1], 16) == int(at[1], 16) + 2    # the 16-bit STR's next
