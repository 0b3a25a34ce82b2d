"""The virtual STM32F411 board: a MicroPython firmware on ``machine``/``time``
stand-ins in lockstep, ``hexhil run --firmware``, and how a bad firmware is reported."""
import json
import re

import pytest

from hexhil.hil.link import served_firmware
from hexhil.hil.link.board_line import MISTAKES
from hexhil.hil.link.served_firmware import served_firmware as board_firmware
from hexhil.hil.servobus.master_check import MasterCheck
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.scenario import SCHEMA
from hexhil import cli
from hexhil.trace.reader import Trace
from conftest import ROOT, hexhil_in_process as hexhil

EXAMPLE = ROOT / "examples" / "board_tripod.py"

PING = '''
import time
from machine import UART, Pin
uart = UART(2, baudrate=1000000, timeout=5, timeout_char=1)
direction = Pin("A1", Pin.OUT, value=0)

def packet(i, instr, params=b""):
    b = bytes((i, len(params) + 2, instr)) + params
    return b"\\xff\\xff" + b + bytes(((~sum(b)) & 0xFF,))

def ping(i):
    direction.value(1)
    uart.write(packet(i, 1))
    uart.flush()
    direction.value(0)
    return uart.read(6)
'''


def board_run(tmp_path, source, *extra):
    """(completed process, console lines from the trace) of ``source`` on the board."""
    main = tmp_path / "main.py"
    main.write_text(source)
    trace = tmp_path / "t.mcap"
    r = hexhil("run", "scenarios/flat-tripod.toml", "--firmware", str(main), "--out",
               str(trace), *extra)
    return r, console(trace)


def console(trace):
    with Trace(trace) as t:
        if "/telemetry" not in t.topics():
            return []
        return [json.loads(m.data)["text"] for m in t.messages(["/telemetry"])
                if json.loads(m.data).get("event") == 0]


def summary(r):
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_the_example_pings_moves_reads_and_walks_the_same_twice(tmp_path):
    runs = []
    for k in range(2):
        trace = tmp_path / f"{k}.mcap"
        runs.append((summary(hexhil("run", "scenarios/flat-tripod.toml", "--firmware",
                                    str(EXAMPLE), "--json", "--out", str(trace))),
                     console(trace)))
    (s, lines), (s2, _) = runs
    assert s["firmware_runtime"] == "micropython-board" and s["sim_time_s"] == 30.0
    assert s["body"]["dx_m"] >= 0.3
    assert s["serial_digest"] == s2["serial_digest"]
    assert lines[0] == "ping: 18 servos answer: %s" % list(range(1, 19))
    moved = re.match(r"servo 1 moved from (\d+) to (\d+)", lines[1])
    assert moved and int(moved[2]) - int(moved[1]) > 30
    assert lines[2] == "switches pressed: [0, 0, 0, 0, 0, 0]"
    assert not s["faults"]


def test_a_firmware_that_never_raises_the_direction_line_hears_nothing(tmp_path):
    src = EXAMPLE.read_text().replace("RAISE_DIRECTION = True", "RAISE_DIRECTION = False")
    r, lines = board_run(tmp_path, src, "--duration", "2", "--json")
    s = summary(r)
    assert lines[0] == "ping: 0 servos answer: []"
    assert s["faults"]["tx_while_receiving"] > 18
    assert s["body"]["dx_m"] == pytest.approx(0.0, abs=0.01)


def test_a_firmware_that_never_lowers_it_loses_the_replies(tmp_path):
    src = PING.replace("    direction.value(0)\n", "") + \
        "print([i for i in range(1, 19) if ping(i)])\nwhile True:\n    time.sleep_ms(20)\n"
    r, lines = board_run(tmp_path, src, "--duration", "0.5", "--json")
    assert lines == ["[]"]
    assert summary(r)["faults"]["rx_while_transmitting"] == 18


def test_uart_timeouts_and_busy_waits_run_in_virtual_time(tmp_path):
    src = PING + '''
t0 = time.ticks_us()
r = ping(30)                      # no servo 30: read gives up after timeout=5 ms
t1 = time.ticks_us()
direction.value(1); uart.write(packet(1, 1)); uart.flush(); direction.value(0)
while not uart.any():             # busy-wait: each call costs the quantum
    pass
t2 = time.ticks_us()
print(r, time.ticks_diff(t1, t0), time.ticks_diff(t2, t1), uart.read(6))
print("at", time.ticks_us())      # the board ahead of the host: the line has its time
while True:
    time.sleep_ms(20)
'''
    r, lines = board_run(tmp_path, src, "--duration", "0.2")
    assert r.returncode == 0, r.stderr
    with Trace(tmp_path / "t.mcap") as t:
        stamps_us = [m.log_time_ns // 1000 for m in t.messages(["/telemetry"])]
    assert lines[1] == f"at {stamps_us[1]}", (lines, stamps_us)
    fields = lines[0].split(" ", 3)
    assert fields[0] == "None" and 5000 <= int(fields[1]) < 5200
    # 60 us of PING, 500 us of Return Delay, the first status byte: 10 us
    assert 570 <= int(fields[2]) < 600, fields
    assert fields[3] == repr(b"\xff\xff\x01\x02\x00\xfc")


def test_switch_pins_and_their_irq_follow_the_switches(tmp_path):
    main = tmp_path / "main.py"
    main.write_text('''
import json, time
from machine import Pin
falls = []
pins = [Pin(n, Pin.IN, Pin.PULL_UP) for n in ("B0", "B1", "B2", "B3", "B4", "B5")]
pins[3].irq(lambda p: falls.append(time.ticks_ms()), Pin.IRQ_FALLING)
before = [p.value() for p in pins]
time.sleep_ms(100)
print("event 3", json.dumps({"before": before, "after": [p.value() for p in pins],
                             "falls": falls}))
while True:
    time.sleep_ms(20)
''')
    sc = {s: {} for s in SCHEMA}
    sc["_path"] = "<test>"
    result = Simulator(sc, 0, switches=lambda t_us: 0b1000 if t_us >= 50_000 else 0).run(
        0.2, firmware=board_firmware(main))
    assert result.exit_code == 0, result.stderr_tail
    assert result.switch_edges == 1
    assert result.firmware.other == {"before": [1] * 6, "after": [1, 1, 1, 0, 1, 1], "falls": [50]}


@pytest.mark.parametrize("tail,message", [
    ("raise ValueError('boom')\n",
     r"the firmware main.py crashed at t=0\.\d+ s \(exit 1\): ValueError: boom"),
    ("while True:\n    time.ticks_us()\n",
     r"the firmware main.py hung: no UART write, direction turn or sleep for 2 "
     r"virtual seconds"),
    ("pass\n", r"the firmware main.py exited at t=0\.\d+ s, before the run's end \(30 s\)"),
])
def test_a_bad_firmware_is_one_line_and_keeps_its_trace(tmp_path, tail, message):
    """Quiet: the firmware's own console (its traceback too) is not on stderr."""
    r, _ = board_run(tmp_path, PING + "ping(1)\ntime.sleep_ms(50)\n" + tail, "--quiet")
    assert r.returncode == 1 and "Traceback" not in r.stderr   # a verdict, not bad input
    assert len(r.stderr.strip().splitlines()) == 1 and re.search(message, r.stderr), r.stderr
    with Trace(tmp_path / "t.mcap") as t:
        assert len(list(t.messages(["/serial"]))) == 2   # the ping and its status


def test_a_firmware_that_hangs_outside_virtual_time(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(served_firmware, "HANG_WALL_S", 1.0)
    main = tmp_path / "main.py"
    main.write_text(PING + "ping(1)\nwhile True:\n    pass\n")
    trace = tmp_path / "t.mcap"
    code = cli.main(["run", "scenarios/flat-tripod.toml", "--firmware", str(main), "--out",
                     str(trace)])
    err = capsys.readouterr().err
    assert code == 1 and err.startswith("hexhil: the firmware main.py hung: no link message for 1 s "
                                        "of wall time"), err
    with Trace(trace) as t:
        assert t.topics()


def test_a_firmware_that_is_not_a_file(tmp_path):
    r = hexhil("run", "scenarios/flat-tripod.toml", "--firmware", str(tmp_path))
    assert r.returncode == 2
    assert r.stderr.strip() == f"hexhil: --firmware {tmp_path}: not a file (give a " \
        "MicroPython main file, an STM32F411 ELF or an executable)"


def test_our_firmware_runs_on_the_board_back_end():
    """firmware/main.py picks hal/board.py (unchanged) on the virtual board and walks."""
    s = summary(hexhil("run", "scenarios/flat-tripod.toml", "--firmware", "firmware/main.py",
                       "--duration", "6", "--json"))
    assert s["firmware_runtime"] == "micropython-board"
    assert s["unhandled_exceptions"] == 0 and s["state"] == "walking"
    assert s["cycles"] >= 250 and s["body"]["dx_m"] > 0.15
    assert not s["faults"]


def test_the_master_check_names_both_direction_mistakes(tmp_path):
    main = tmp_path / "main.py"
    main.write_text(PING + '''
uart.write(packet(1, 1))                 # direction low: never reaches the line
direction.value(1)
uart.write(packet(2, 1))                 # ... and never lowered: the status is lost
time.sleep_ms(5)
direction.value(0)
while True:
    time.sleep_ms(20)
''')
    sc = {s: {} for s in SCHEMA}
    sc["_path"] = "<test>"
    sim = Simulator(sc, 0)
    sim.bus.monitor = check = MasterCheck()
    result = sim.run(0.1, firmware=board_firmware(main))
    assert result.exit_code == 0, result.stderr_tail
    assert check.counts["tx_while_receiving"] == 1 and check.counts["rx_while_transmitting"] == 1
    assert result.faults == {"tx_while_receiving": 1, "rx_while_transmitting": 1}
    assert [e["kind"] for e in check.summary()["events"]] == list(MISTAKES)


def test_a_board_trace_replays_into_its_firmware_and_a_change_diverges(tmp_path):
    trace = tmp_path / "t.mcap"
    assert hexhil("run", "scenarios/flat-tripod.toml", "--firmware", str(EXAMPLE),
                  "--duration", "2", "--out", str(trace)).returncode == 0
    same = hexhil("replay", str(trace), "--firmware", str(EXAMPLE))
    assert same.returncode == 0 and same.stdout.startswith("identical:"), same.stdout
    changed = tmp_path / "main.py"
    changed.write_text(EXAMPLE.read_text().replace("STEP, LIFT, PERIOD_S, CYCLE_MS = 0.05",
                                                   "STEP, LIFT, PERIOD_S, CYCLE_MS = 0.06"))
    diff = hexhil("replay", str(trace), "--firmware", str(changed))
    assert diff.returncode == 1 and " on uart:" in diff.stdout, diff.stdout


def test_a_firmware_that_never_touches_the_board(tmp_path):
    main = tmp_path / "main.py"
    main.write_text("print('hello')\n")
    r = hexhil("run", "scenarios/flat-tripod.toml", "--firmware", str(main))
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1
    assert "exited with code 0 before it connected to the link" in r.stderr, r.stderr


def test_pyb_can_sends_and_receives_on_the_runs_bus(tmp_path):
    main = tmp_path / "main.py"
    main.write_text('''
import json, time, pyb
can = pyb.CAN(1, pyb.CAN.NORMAL, baudrate=500000)
can.send(b"\\x07", 0x42)
t0 = time.ticks_us()
while not can.any():              # busy-waits: asks the host at most every millisecond
    pass
arb_id, rtr, fmi, data = can.recv(0, timeout=0)
print("event 3", json.dumps({"id": arb_id, "data": list(data),
                             "waited_us": time.ticks_diff(time.ticks_us(), t0)}))
while True:
    time.sleep_ms(20)
''')

    class Sender:
        period_us = 50_000

        def __init__(self, sim):
            self.sim = sim

        def tick(self, t_us):
            self.sim.send_can(0x123, bytes((t_us // 1000,)))

    sc = {s: {} for s in SCHEMA}
    sc["_path"] = "<test>"
    sim = Simulator(sc, 0)
    sim.add_node(Sender(sim))
    result = sim.run(0.2, firmware=board_firmware(main))
    assert result.exit_code == 0, result.stderr_tail
    assert result.firmware.other["id"] == 0x123 and result.firmware.other["data"] == [50]
    assert 50_000 <= result.firmware.other["waited_us"] < 51_100
    assert sum(result.can_frames.values()) == 1
