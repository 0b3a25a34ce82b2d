"""STM32F411 ELFs on the emulated board: the C
tripod built with ``--target stm32f411`` walks; a bare-metal firmware written from RM0383
alone pings the 18 servos through the PA1 buffer, and built without driving PA1 or at the
wrong baud gets no replies and the run says why; two tasks share the core through
PendSV/SysTick; interrupt- and DMA-driven UART exchanges work; a HardFault is one line.
The firmwares are tests/elf_firmware/ and the docs' first ELF (docs/elf-firmware.md)."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from elftools.elf.elffile import ELFFile

from hexhil.hil.run_result import Ending
from hexhil import c_sdk
from hexhil.run_summary import run
from hexhil.trace.reader import Trace, info
from conftest import ROOT, hexhil_in_process

FW = ROOT / "tests" / "elf_firmware"
FLAT = str(ROOT / "scenarios" / "flat-tripod.toml")
AX12_UNITS_PER_RAD = 1023 / (300 * 3.141592653589793 / 180)


@pytest.fixture(scope="module")
def elfs(tmp_path_factory):
    """name -> ELF of every firmware here, built as a user would."""
    out = tmp_path_factory.mktemp("elf_firmware")
    builds = {"c_tripod": ([ROOT / "examples" / "c_tripod" / "main.c"], (), False),
              "bare": ([FW / "bare_metal.c"], (), True),
              "bare_no_direction": ([FW / "bare_metal.c"], ("-DNO_DIRECTION",), True),
              "bare_wrong_baud": ([FW / "bare_metal.c"], ("-DSERVO_BAUD=57600",), True),
              "two_tasks": ([FW / "two_tasks.c"], (), False),
              "uart_it": ([FW / "servo_async.c"], (), False),
              "uart_dma": ([FW / "servo_async.c"], ("-DUSE_DMA",), False),
              "hardfault": ([FW / "hardfault.c"], (), False),
              "unhandled_irq": ([FW / "unhandled_irq.c"], (), False),
              "switches_timer": ([FW / "switches_timer.c"], (), False)}
    return {name: str(c_sdk.build([str(s) for s in srcs], out / f"{name}.elf", flags,
                                  "stm32f411", bare))
            for name, (srcs, flags, bare) in builds.items()}


def console(trace: Path) -> list[str]:
    """What the firmware printed (USART1, semihosting): the trace's /telemetry lines."""
    with Trace(trace) as t:
        return [json.loads(m.data)["text"] for m in t.messages(["/telemetry"])
                if json.loads(m.data).get("event") == 0]


def packets(trace: Path) -> list[dict]:
    with Trace(trace) as t:
        if "/serial" not in t.topics():   # nothing ever reached the line
            return []
        return [p for _, msg in t.decoded(["/serial"]) for p in msg["packets"]]


def run_traced(elf: str, tmp_path: Path, duration_s: float):
    trace = tmp_path / "run.mcap"
    summary, result = run(FLAT, duration_s=duration_s, firmware=elf, out=str(trace))
    return summary, result, trace


def test_the_c_tripod_elf_walks_flat_tripod_with_the_same_digest_twice(elfs):
    # 12 s of the scenario's 30: the walk, its CAN and its digest, at 40 % of the cost
    first, result = run(FLAT, duration_s=12.0, firmware=elfs["c_tripod"])
    second, _ = run(FLAT, duration_s=12.0, firmware=elfs["c_tripod"])
    assert first["firmware_runtime"] == "stm32f411-elf" and first["sim_time_s"] == 12.0
    assert result.firmware.other["mcu"]["hclk_hz"] == 100_000_000   # the SDK's SystemInit
    assert first["body"]["dx_m"] >= 0.3, first["body"]
    assert first["faults"] == {}
    assert first["serial_digest"] == second["serial_digest"]


def test_the_bare_metal_firmware_pings_18_servos_moves_one_and_counts_cycles(elfs, tmp_path):
    summary, result, trace = run_traced(elfs["bare"], tmp_path, 1.2)
    assert summary["faults"] == {} and summary["sim_time_s"] == 1.2   # idle in WFI to the end
    assert result.firmware.other["mcu"]["hclk_hz"] == 100_000_000            # its PLL from HSI
    lines = console(trace)
    assert lines[0] == "bare-metal: 18 of 18 servos answered, servo 1 moved", lines
    # DWT's CYCCNT over 1000 SysTick periods: 100 M cycles a virtual second (PLL at 100 MHz)
    cycles = int(re.fullmatch(r"bare-metal: (\d+) cycles in 1000 SysTick ms", lines[1])[1])
    assert abs(cycles - 100_000_000) <= 100, cycles
    # a line's time is its newline's end, with no interrupt armed that makes the board
    # sync often: the third line says at which DWT cycle the second one ended, and takes
    # its own bytes' UART time (115200 baud: BRR 868 at 100 MHz, 86.8 us a frame) more
    ended = int(re.fullmatch(r"bare-metal: that line ended at cycle (\d+)", lines[2])[1])
    with Trace(trace) as t:
        logged = [m.log_time_ns * 1e-9 for m in t.messages(["/telemetry"])]
    (t2, _), (t3, _) = result.console[1:3]
    assert logged[1:3] == pytest.approx([t2, t3], abs=1e-9)
    assert 0 <= t2 - ended / 100e6 < 1e-3, (t2, ended)            # the boot before DWT's 0
    assert 0 <= t3 - t2 - (len(lines[2]) + 1) * 10 * 868 / 100e6 < 20e-6, (t2, t3)
    seen = packets(trace)
    pings = [p["id"] for p in seen if p["direction"] == "tx" and p["instruction"] == "PING"]
    replies = [p["id"] for p in seen if p["direction"] == "rx" and p["id"] in range(1, 19)]
    assert pings == list(range(1, 19))
    assert replies[:18] == list(range(1, 19)) and len(replies) == 20   # + the two WRITEs
    with Trace(trace) as t:
        last = [msg for _, msg in t.decoded(["/servos"])][-1]
    servo1 = next(s for s in last["servos"] if s["id"] == 1)
    assert servo1["torque_enabled"]
    assert abs(servo1["position_rad"] - (612 - 511.5) / AX12_UNITS_PER_RAD) < 0.05


def test_built_without_driving_pa1_it_gets_no_replies_and_the_run_names_the_mistake(
        elfs, tmp_path):
    summary, _, trace = run_traced(elfs["bare_no_direction"], tmp_path, 0.1)
    assert summary["faults"].get("tx_while_receiving", 0) >= 18, summary["faults"]
    assert console(trace)[0] == "bare-metal: 0 of 18 servos answered, servo 1 did not answer"
    assert [p for p in packets(trace) if p["direction"] == "rx"] == []


def test_a_wrong_usart2_baud_gets_no_replies_and_the_run_says_so(elfs, tmp_path):
    trace = tmp_path / "run.mcap"
    proc = hexhil_in_process("run", FLAT, "--duration", "0.1", "--firmware",
                             elfs["bare_wrong_baud"], "--out", str(trace))
    assert proc.returncode == 0, proc.stderr
    fault_line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("faults:"))
    assert "baud" in fault_line, proc.stdout
    assert console(trace)[0] == "bare-metal: 0 of 18 servos answered, servo 1 did not answer"
    assert [p for p in packets(trace) if p["direction"] == "rx"] == []
    with Trace(trace) as t:
        said = " ".join(msg["message"] for _, msg in t.decoded(["/faults"]))
    assert "57604" in said and "1000000" in said, said   # BRR 868 at 50 MHz, the line's


def test_two_tasks_switched_by_pendsv_both_run_with_their_registers_intact(elfs, tmp_path):
    summary, _, trace = run_traced(elfs["two_tasks"], tmp_path, 0.55)
    assert summary["faults"] == {}
    lines = console(trace)
    assert lines[0] == "two tasks: starting"
    runs = {"a": [], "b": []}
    for line in lines[1:]:
        m = re.fullmatch(r"task ([ab]): (\d+) runs at (\d+) ms", line)
        assert m, line                            # a lost FPU register would say CORRUPT
        runs[m[1]].append(int(m[2]))
    for name, counts in runs.items():
        # each task runs every other tick: ~50 runs each 100 ms, always more
        assert len(counts) == 5 and counts == sorted(counts), (name, counts)
        assert all(45 <= b - a <= 55 for a, b in zip(counts, counts[1:])), (name, counts)


@pytest.mark.parametrize("name, mode", [("uart_it", "it"), ("uart_dma", "dma")])
def test_interrupt_and_dma_uart_exchanges_reach_every_servo(elfs, tmp_path, name, mode):
    summary, _, trace = run_traced(elfs[name], tmp_path, 0.1)
    assert summary["faults"] == {}
    m = re.fullmatch(rf"{mode}: (\d+) of 18 servos answered, servo 1 at (-?\d+)",
                     console(trace)[0])
    assert m and int(m[1]) == 18 and 0 <= int(m[2]) <= 1023, console(trace)
    seen = packets(trace)
    assert [p["id"] for p in seen if p["direction"] == "rx"] == [*range(1, 19), 1]


def test_switch_edges_arrive_as_exti_interrupts_and_tim2_counts_at_1_khz(elfs, tmp_path):
    summary, _, trace = run_traced(elfs["switches_timer"], tmp_path, 2.0)
    assert summary["faults"] == {}
    lines = console(trace)
    updates = int(re.fullmatch(r"tim2: (\d+) updates in 500 ms", lines[0])[1])
    assert abs(updates - 500) <= 1, updates   # the phase of TIM2 against SysTick: one update
    said = [re.fullmatch(r"switch (\w\w) (pressed|released) at (\d+) ms", ln).groups()
            for ln in lines[1:]]
    with Trace(trace) as t:
        edges = [(msg["leg_name"], "pressed" if msg["level"] else "released",
                  m.log_time_ns / 1e6) for m, msg in t.decoded(["/switches"])]
    assert len(edges) >= 2 and len(said) == len(edges)   # the robot sags onto its switches
    for (leg, what, t_ms), (f_leg, f_what, f_ms) in zip(sorted(edges), sorted(said)):
        assert (leg, what) == (f_leg, f_what) and abs(int(f_ms) - t_ms) <= 2


def test_a_hardfault_is_one_line_with_the_pc_and_the_function_and_the_trace_is_kept(
        elfs, tmp_path):
    with open(elfs["hardfault"], "rb") as f:
        sym = next(s for s in ELFFile(f).get_section_by_name(".symtab").iter_symbols()
                   if s.name == "fault_here")
    start, size = sym["st_value"] & ~1, sym["st_size"]
    trace = tmp_path / "run.mcap"
    summary, result = run(FLAT, duration_s=0.5, firmware=elfs["hardfault"], out=str(trace))
    ending = result.ending           # a verdict on the firmware, as any firmware's crash
    assert ending.kind is Ending.CRASHED and summary["ending"]["kind"] == "crashed"
    line = ending.reason
    assert "\n" not in line and "fault_here" in line and "fault" in line.lower()
    pc = int(re.search(r"PC (0x[0-9a-fA-F]+)", line)[1], 16)
    assert start <= pc < start + size, (hex(pc), hex(start))
    assert 0 < ending.t_s < 0.5 and ending.last_lines == ("hardfault: about to fault",)
    assert console(trace) == ["hardfault: about to fault"]          # the trace is kept
    assert "/body" in [t["topic"] for t in info(trace)["topics"]]
    proc = hexhil_in_process("run", FLAT, "--duration", "0.5", "--firmware", elfs["hardfault"])
    assert proc.returncode == 1 and proc.stderr.endswith(f"\nhexhil: {line}\n"), proc.stderr
    printed = re.fullmatch(r"\[ *(\d+\.\d{6}) s\] hardfault: about to fault",
                           proc.stderr.splitlines()[0])      # the console, live
    assert printed and 0 < float(printed[1]) <= ending.t_s, proc.stderr


def test_an_interrupt_without_a_handler_is_a_lockup_in_one_line_and_a_failing_case(
        elfs, tmp_path):
    with open(elfs["unhandled_irq"], "rb") as f:
        loop = next(s for s in ELFFile(f).get_section_by_name(".symtab").iter_symbols()
                    if s.name == "Default_Handler")["st_value"] & ~1
    trace = tmp_path / "run.mcap"
    _, result = run(FLAT, duration_s=0.5, firmware=elfs["unhandled_irq"], out=str(trace))
    assert result.ending.kind is Ending.CRASHED
    line = result.ending.reason
    assert "\n" not in line and "a lockup" in line and "interrupt 29" in line, line
    assert f"PC 0x{loop:08x} in Default_Handler" in line, line
    assert console(trace) == ["unhandled: enabling TIM3_IRQn"]     # the trace is kept
    case = tmp_path / "short.toml"
    case.write_text(f'[case]\nscenario = "{FLAT}"\nduration_s = 0.2\n\n[[expect]]\n'
                    'name = "no firmware exception"\nkind = "no_exception"\n')
    proc = hexhil_in_process("test", str(case), "--firmware", elfs["unhandled_irq"])
    assert proc.returncode == 1 and "a lockup" in proc.stdout and "FAIL" in proc.stdout, \
        proc.stdout + proc.stderr


def test_the_docs_first_elf_builds_for_both_targets_and_answers_every_ping(tmp_path):
    doc = (ROOT / "docs" / "elf-firmware.md").read_text()
    main = tmp_path / "main.c"
    main.write_text(doc.split("```c\n", 1)[1].split("```", 1)[0])
    for target, out in (("stm32f411", "fw.elf"), ("host", "fw")):
        proc = subprocess.run([sys.executable, "-m", "hexhil.cli", "sdk", "build",
                               "--target", target, str(main), "-o", str(tmp_path / out)],
                              cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
    summary, _, trace = run_traced(str(tmp_path / "fw.elf"), tmp_path, 2.0)
    assert summary["faults"] == {}
    assert console(trace)[:2] == ["50 of 50 pings answered", "100 of 100 pings answered"]
    host, result = run(FLAT, duration_s=1.0, firmware=str(tmp_path / "fw"))
    assert host["faults"] == {} and result.firmware.timeouts == 0
