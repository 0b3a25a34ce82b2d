"""A firmware that stops before it connects, or a line nobody answers, is reported with its
real cause: micropython prints its traceback on stdout, a binary
``.py`` is not a source, a wrong baud reaches no servo, and a run where no servo answered
says which of the master's mistakes it saw."""

import can
import pytest

from ctrl_c import sigint_default
from hexhil import cli
from conftest import HEXHIL, ROOT

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
    # a firmware that never starts is the run's verdict (exit 1), in one line
    assert code == 1 and len(err.strip().splitlines()) == 1, err
    assert err.strip().endswith(cause), err


def test_a_binary_file_named_py_is_refused_as_not_a_source(tmp_path, capsys):
    main = tmp_path / "main.py"
    main.write_bytes(bytes(range(256)) * 4)
    code, _, err = run_cli(capsys, "--firmware", str(main), "--duration", "0.2")
    assert code == 2
    assert err.strip() == (f"hexhil: --firmware {main}: not a MicroPython source file "
                           "(it holds binary data, not UTF-8 text)"), err


PING = '''
import time
from machine import UART, Pin
uart = UART(2, baudrate=1000000, timeout=5, timeout_char=1)
direction = Pin("A1", Pin.OUT, value=0)

def ping(i, raise_pin=True):
    b = bytes((i, 2, 1))
    direction.value(1 if raise_pin else 0)
    uart.write(b"\\xff\\xff" + b + bytes(((~sum(b)) & 0xFF,)))
    uart.flush()
    direction.value(0)
    return uart.read(6)

while True:
    for i in IDS:
        ping(i, RAISE)
    time.sleep_ms(20)
'''


@pytest.mark.parametrize("ids,raise_pin,cause", [
    ((1, 2), False, "no servo answered: 4 writes went out while the direction pin (A1) "
                    "was low (tx_while_receiving)"),
    ((30, 31), True, "no servo answered: the packets went to IDs 30, 31, and no servo on "
                     "the line has them (IDs 1-18)"),
])
def test_a_run_where_no_servo_answered_says_why(tmp_path, capsys, ids, raise_pin, cause):
    main = tmp_path / "main.py"
    main.write_text(f"IDS = {ids!r}\nRAISE = {raise_pin}\n" + PING)
    code, out, _ = run_cli(capsys, "--firmware", str(main), "--duration", "0.05", "--json")
    assert code == 0
    assert cause in out.splitlines(), out


def test_a_run_where_servos_answered_has_no_such_line(tmp_path, capsys):
    main = tmp_path / "main.py"
    main.write_text("IDS = (1,)\nRAISE = True\n" + PING)
    code, out, _ = run_cli(capsys, "--firmware", str(main), "--duration", "0.05", "--json")
    assert code == 0 and "no servo answered" not in out
    assert '"no_servo_answered": null' in out


def _c_tripod_at(tmp_path, baud: int) -> str:
    from hexhil import c_sdk

    src = (ROOT / "examples" / "c_tripod" / "main.c").read_text()
    assert "huart2.Init.BaudRate = 1000000;" in src
    main = tmp_path / f"tripod_{baud}.c"
    main.write_text(src.replace("huart2.Init.BaudRate = 1000000;",
                                f"huart2.Init.BaudRate = {baud};"))
    return str(c_sdk.build([str(main)], tmp_path / f"tripod_{baud}"))


def test_a_c_firmware_at_the_wrong_baud_hears_no_servo_and_the_run_says_so(tmp_path, capsys):
    """On the robot a 57600 baud USART2 reaches no AX-12 at 1 Mbps: no replies, no walk."""
    code, out, _ = run_cli(capsys, "--firmware", _c_tripod_at(tmp_path, 57600),
                           "--duration", "1", "--json")
    assert code == 0
    assert ("no servo answered: the master's UART ran at 57600 baud, the servos at "
            "1000000 baud") in out.splitlines(), out
    assert '"wrong_baud": 1' in out
    right, out_right, _ = run_cli(capsys, "--firmware", _c_tripod_at(tmp_path, 1000000),
                                  "--duration", "1", "--json")
    assert right == 0 and "no servo answered" not in out_right


def _fault_details(trace) -> list[tuple[str, str]]:
    from hexhil.trace.reader import Trace

    with Trace(trace) as t:
        return [(v["name"], v["message"]) for _, v in t.decoded(["/faults"])]


def test_faults_are_plain_text_from_the_board_and_the_c_sdk(tmp_path):
    """/faults holds the fault's detail as text, whichever board saw the mistake."""
    from hexhil.run_summary import run

    main = tmp_path / "main.py"
    main.write_text("IDS = (1,)\nRAISE = False\n" + PING)
    run(SCENARIO, duration_s=0.05, out=str(tmp_path / "board.mcap"), firmware=str(main))
    board = [d for n, d in _fault_details(tmp_path / "board.mcap") if n == "tx_while_receiving"]
    src = (ROOT / "tests" / "c_firmware" / "no_transmitter.c")
    from hexhil import c_sdk

    exe = c_sdk.build([str(src)], tmp_path / "no_tx")
    run(SCENARIO, duration_s=0.05, out=str(tmp_path / "c.mcap"), firmware=str(exe))
    c = [d for n, d in _fault_details(tmp_path / "c.mcap") if n == "tx_while_receiving"]
    assert board and c
    assert board[0] == c[0] == ("6 bytes written while the direction pin (A1) was low: they "
                                "did not reach the line")


def test_can_endpoint_frames_are_the_firmwares_only():
    import hexhil as hx

    scenario = hx.load_scenario(SCENARIO)
    run = hx.Run(scenario, runtime=hx.Runtime.CPYTHON_INPROCESS, duration_s=0.3)
    port = run.can_endpoint()
    other = run.can_endpoint()

    class Talker:
        period_us = 100_000

        def tick(self, t_us):
            other.send(can.Message(arbitration_id=0x7F0, data=b"\x01", is_extended_id=False))

    run.add_node(Talker())
    run.run()
    ids = {m.arbitration_id for m in port.frames()}
    assert ids and 0x7F0 not in ids


SAYS_AND_CRASHES = r'''
#include "stm32f4xx_hal.h"
#include <signal.h>
#include <stdio.h>

int main(void)
{
    HAL_Init();
    printf("booted\n");
    HAL_Delay(300);
    printf("about to crash\n");
    HAL_Delay(100);
    raise(SIGSEGV);
    return 0;
}
'''


def _console_lines(trace) -> list[tuple[float, str]]:
    from hexhil.trace.reader import Trace

    with Trace(trace) as t:
        return [(m.log_time_ns * 1e-9, v["text"]) for m, v in t.decoded(["/telemetry"])
                if v.get("event") == 0]


def test_a_c_firmwares_console_is_in_the_trace_when_printed_and_a_crash_keeps_body(tmp_path):
    from hexhil import c_sdk
    from hexhil.run_summary import run
    from hexhil.trace.reader import Trace
    from hexhil.protocol.errors import UserError

    src = tmp_path / "says.c"
    src.write_text(SAYS_AND_CRASHES)
    exe = c_sdk.build([str(src)], tmp_path / "says")
    trace = tmp_path / "c.mcap"
    try:
        run(SCENARIO, duration_s=2.0, out=str(trace), firmware=str(exe))
    except UserError:
        pass                        # a crash: the trace is kept either way
    lines = _console_lines(trace)
    assert [text for _, text in lines] == ["booted", "about to crash"]
    assert lines[0][0] < 0.05 and 0.29 < lines[1][0] < 0.35, lines   # when printed
    with Trace(trace) as t:
        assert "/body" in t.topics()


def test_a_board_firmwares_prints_are_stamped_when_printed(tmp_path):
    from hexhil.run_summary import run

    main = tmp_path / "main.py"
    main.write_text("import time\nprint('one')\ntime.sleep_ms(300)\nprint('two')\n"
                    "while True:\n    time.sleep_ms(20)\n")
    run(SCENARIO, duration_s=1.0, out=str(tmp_path / "b.mcap"), firmware=str(main))
    lines = _console_lines(tmp_path / "b.mcap")
    assert [text for _, text in lines] == ["one", "two"]
    assert lines[0][0] < 0.05 and 0.29 < lines[1][0] < 0.35, lines


def test_ctrl_c_keeps_the_trace_says_so_and_prints_the_summary(tmp_path):
    import json
    import signal
    import subprocess
    import sys
    import time

    from hexhil.trace.reader import Trace

    trace = tmp_path / "long.mcap"
    proc = subprocess.Popen([*HEXHIL, "run", SCENARIO,
                             "--duration", "600", "--python", "cpython-inprocess", "--out",
                             str(trace), "--json"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=sigint_default)
    from hexhil.trace.target import partial_of

    partial = partial_of(trace)        # a run writes beside its target until it ends
    deadline = time.monotonic() + 60
    while (not partial.exists() or partial.stat().st_size < 200_000) and time.monotonic() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert len(err.strip().splitlines()) == 1 and "interrupted at t=" in err, err
    assert f"the trace {trace} is kept" in err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["interrupted"] is True and summary["sim_time_s"] > 0
    with Trace(trace) as t:
        assert "/body" in t.topics()


def test_a_run_closed_without_running_leaves_no_warning():
    import subprocess
    import sys

    code = ("import gc, hexhil as hx\n"
            f"r = hx.Run(hx.load_scenario({SCENARIO!r}))\n"
            "r.close()\ndel r\ngc.collect()\n"
            f"with hx.Run(hx.load_scenario({SCENARIO!r})):\n    pass\ngc.collect()\n")
    p = subprocess.run([sys.executable, "-W", "default", "-c", code], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "not properly shut down" not in p.stderr, p.stderr


def test_a_hexapod_runs_result_has_its_worlds_final_state():
    import hexhil as hx
    from hexhil.hil.run_result import HexapodOutcome

    run = hx.Run(hx.load_scenario(SCENARIO), runtime=hx.Runtime.CPYTHON_INPROCESS,
                 duration_s=0.5)
    world = run.run().world
    assert isinstance(world, HexapodOutcome)
    assert set(world.as_dict()) == {"x_m", "y_m", "z_m", "yaw_deg", "feet_on_ground"}
    assert 0.02 < world.z_m < 0.3 and world.feet_on_ground is not None
    assert 0 <= world.feet_on_ground <= 6


def test_junit_testcases_have_their_own_times():
    from hexhil.expect import junit
    from hexhil.expect.verdicts import Outcome
    from hexhil.expect.case_runs import CaseResult

    outcomes = (Outcome("c", "quick", "protocol", "0", "0", True, time_s=0.002),
                Outcome("c", "slow", "tactile_rule", "h", "h_k", True, time_s=0.75))
    result = CaseResult("c", 1, outcomes, {"wall_time_s": 9.0}, None)
    root = junit.to_xml([result]).getroot()
    assert [c.get("time") for c in root.findall(".//testcase")] == ["0.002", "0.750"]
    assert root.find("testsuite").get("time") == "9.000"
