"""The masked-spin limit from the command line and the expectation file (``--masked-limit``,
``[case] masked_limit_s``), and ``hexhil test``'s live console: each line on stderr after
its virtual time, silenced by ``--quiet``, the last lines in ``--json``."""
import json

import pytest

from hexhil.firmware import main as firmware_main
from hexhil.expect import spec
from hexhil.lockstep_run import Run
from mcu_elf import build
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil_in_process as hexhil

SPIN = "still running after"


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A case whose ELF's UsageFault handler loops for ever (tests/mcu/fault_handler.c)."""
    tmp = tmp_path_factory.mktemp("masked")
    elf = build(tmp, "fault_handler.c", "HANDLER=2")
    path = tmp / "spin.toml"
    path.write_text(f'[case]\nscenario = "{ROOT}/scenarios/flat-tripod.toml"\n'
                    f'duration_s = 0.3\nfirmware = "{elf}"\nmasked_limit_s = 0.03\n\n'
                    '[[expect]]\nname = "no firmware exception"\nkind = "no_exception"\n')
    return path, elf


def test_hexhil_test_shows_the_console_live_and_in_json_and_takes_the_case_limit(case):
    r = hexhil("test", case[0], "--json")
    assert r.returncode == 1, r.stdout + r.stderr
    # each line at its semihosting call: 17 us into the boot at HSI 16 MHz
    assert "[  0.000017 s] usage cfsr 00010000" in r.stderr.splitlines(), r.stderr
    out = json.loads(r.stdout.splitlines()[-1])
    (only,) = out["cases"]
    assert not out["passed"] and [c["text"] for c in only["console"]] == [
        "boot 000b0075", "usage cfsr 00010000"]
    assert only["ending"]["kind"] == "crashed" and f"{SPIN} 0.03" in only["ending"]["reason"]


def test_the_command_line_limit_of_hexhil_test_wins_and_quiet_silences_the_console(case):
    r = hexhil("test", case[0], "--masked-limit", "0.05", "--quiet")
    assert r.returncode == 1 and f"{SPIN} 0.05" in r.stdout, r.stdout
    assert "usage cfsr" not in r.stderr, r.stderr


def test_hexhil_run_takes_the_limit_and_refuses_it_without_an_elf(case):
    r = hexhil("run", "scenarios/flat-tripod.toml", "--firmware", case[1], "--duration", "0.3",
               "--masked-limit", "0.04", "--quiet")
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and f"{SPIN} 0.04" in r.stderr, \
        r.stderr
    with pytest.raises(UserError, match="masked_limit_s needs an STM32F411 ELF"):
        Run(ROOT / "scenarios" / "flat-tripod.toml", masked_limit_s=1.0)


def test_a_case_limit_must_be_above_zero(case, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(case[0].read_text().replace("masked_limit_s = 0.03", "masked_limit_s = 0"))
    with pytest.raises(UserError, match="case.masked_limit_s' must be above 0 s"):
        spec.load(bad)


def test_a_print_of_a_firmware_in_process_is_a_console_line_as_a_child_process_s():
    def main(board):
        print("in process: hello", end="\n")
        print("second ", end="")
        print("line")
        firmware_main.main(board)

    with Run(ROOT / "scenarios" / "flat-tripod.toml", runtime="cpython-inprocess",
             duration_s=0.05) as run:
        result = run.run(None, main)
    assert [text for _, text in result.console] == ["in process: hello", "second line"]
