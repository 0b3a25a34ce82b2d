"""A robot's logs in: a logic analyser's capture of the servo line read, decoded and
checked (host_tools/trace/logic_capture.py, servo_capture.py, the master check on a
capture). The capture is our firmware's 0.5 s walk on 18 AX-12s (lockstep, micropython)
drawn at 8 MHz with its direction channel and written by sigrok-cli; best of 3."""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

from bench import Row
from hexhil.hil import scenario
from hexhil.hil.run.lockstep import Simulator
from hexhil.dynamixel.conformance.capture import check_capture
from hexhil.trace import recorder as rec
from hexhil.trace.logic_capture import read_sr
from hexhil.trace.protobuf import SerialBytes
from hexhil.trace.reader import Trace
from hexhil.trace.servo_capture import decode_line
from tests import uart_wave

RATE_HZ = 8_000_000
ROUNDS = 3


def _best(fn) -> float:
    best = float("inf")
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run() -> list[Row]:
    with tempfile.TemporaryDirectory() as d:
        trace = Path(d) / "run.mcap"
        s = {section: {} for section in scenario.SCHEMA}
        with rec.Recorder(trace, {"scenario": "defaults"}) as r:
            Simulator(s, seed=0, recorder=r).run(duration_s=0.5, python="micropython")
        with Trace(trace) as tr:
            bursts = [(m.log_time_ns // 1000, b.direction, bytes(b.data))
                      for m in tr.messages(["/serial"])
                      if (b := SerialBytes.FromString(m.data)).data]
        sr = uart_wave.write_sr(Path(d) / "run.sr",
                                uart_wave.samples(bursts, 1_000_000, RATE_HZ, direction=True),
                                RATE_HZ)
        capture = read_sr(sr)
        n = len(capture.samples)
        read_s = _best(lambda: read_sr(sr))
        decode_s = _best(lambda: decode_line(capture))
        check_s = _best(lambda: check_capture(sr))
    note = f"{n / 1e6:.1f} M samples at 8 MHz, 1 Mbit/s line"
    return [Row("capture: read .sr", n / read_s / 1e6, "M samples/s", "", note),
            Row("capture: decode the line (UART, direction, bursts)", n / decode_s / 1e6,
                "M samples/s", "", note),
            Row("capture: master check (read and decode included)", check_s * 1e3, "ms",
                "", f"0.5 s of traffic; {note}")]
