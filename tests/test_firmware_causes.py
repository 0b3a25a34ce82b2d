"""A firmware that stops before it connects, or a line nobody answers, is reported with its
real cause (issue 41 items 4, 5, 11): micropython prints its traceback on stdout, a binary
``.py`` is not a source, a wrong baud reaches no servo, and a run where no servo answered
says which of the master's mistakes it saw."""
from pathlib import Path

import pytest

from host_tools import cli

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = str(ROOT / "scenarios" / "flat-tripod.toml")


def run_cli(capsys, *args):
    code = cli.main(["run", SCENARIO, *args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("source,cause", [
    ("def f(:\n    pass\n",
     "SyntaxError: invalid syntax (main.py, line 1)"),
    ("import machine\n\nuart = machine.UART(2, baudrate=57600)\n",
     "ValueError: the servo line runs at 1000000 baud, not 57600 (main.py, line 3)"),
])
def test_a_micropython_firmware_that_stops_before_the_link_says_why(tmp_path, capsys,
                                                                    source, cause):
    main = tmp_path / "main.py"
    main.write_text(source)
    code, _, err = run_cli(capsys, "--firmware", str(main), "--duration", "0.2")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert err.strip().endswith(cause), err


def test_a_binary_file_named_py_is_refused_as_not_a_source(tmp_path, capsys):
    main = tmp_path / "main.py"
    main.write_bytes(bytes(range(256)) * 4)
    code, _, err = run_cli(capsys, "--firmware", str(main), "--duration", "0.2")
    assert code == 2
    assert err.strip() == (f"hexhil: --firmware {main}: not a MicroPython source file "
                           "(it holds binary data, not UTF-8 text)"), err
