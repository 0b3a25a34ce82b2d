"""Servo bus: lockstep transactions per second and the pty READ round trip the SDK sees."""
from __future__ import annotations

import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench import Row
from hexhil.hil.servobus.line import Bus
from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

ROOT = Path(__file__).resolve().parent.parent


def _bus(return_delay: int) -> Bus:
    servos = [Servo(i) for i in range(1, 19)]
    for s in servos:
        s.table[ax12.RETURN_DELAY_TIME] = return_delay
    return Bus(servos, VirtualClock())


def lockstep_rate(kind: str, seconds: float = 1.0) -> float:
    """Master-side transactions per wall second: one packet out, its status read back."""
    bus = _bus(0)
    if kind == "read":
        pkts = [dxl.read(i, ax12.PRESENT_POSITION, 2) for i in range(1, 19)]
        n_reply = 8
    else:
        pkts = [dxl.write(i, ax12.GOAL_POSITION, (400 + 10 * i).to_bytes(2, "little"))
                for i in range(1, 19)]
        n_reply = 6
    write, read = bus.master_write, bus.master_read
    count = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        for p in pkts:
            write(p)
            if len(read(n_reply, 1000)) != n_reply:
                raise RuntimeError("lost a reply in the benchmark")
        count += len(pkts)
    return count / (time.perf_counter() - t0)


def cycle_virtual_ms(return_delay: int) -> float:
    """Virtual time of one control cycle: 18 position READs and a goal+speed SYNC_WRITE."""
    bus = _bus(return_delay)
    t0 = bus.clock.t_us
    for i in range(1, 19):
        bus.master_write(dxl.read(i, ax12.PRESENT_POSITION, 2))
        bus.master_read(8, 5000)
    bus.master_write(dxl.sync_write(ax12.GOAL_POSITION, 4,
                                    [(i, b"\x00\x02\x00\x01") for i in range(1, 19)]))
    return (bus.clock.t_us - t0) / 1000.0


def pty_round_trips(n: int = 400) -> list[float]:
    """dynamixel-sdk read2ByteTxRx on `hexhil bus --pty`, Return Delay 0, seconds each."""
    import dynamixel_sdk as sdk

    proc = subprocess.Popen([sys.executable, "-m", "hexhil.cli", "bus", "--pty", "--servos", "2"],
                            cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        path = proc.stdout.readline().strip().split(": ", 1)[1]
        port = sdk.PortHandler(path)
        port.openPort()
        ph = sdk.PacketHandler(1.0)
        ph.write1ByteTxRx(port, 1, ax12.RETURN_DELAY_TIME, 0)
        out = []
        for _ in range(n):
            t = time.perf_counter()
            _, res, _ = ph.read2ByteTxRx(port, 1, ax12.PRESENT_POSITION)
            if res == sdk.COMM_SUCCESS:
                out.append(time.perf_counter() - t)
        port.closePort()
        return out
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=10)


def run() -> list[Row]:
    reads = lockstep_rate("read")
    writes = lockstep_rate("write")
    rtt = pty_round_trips()
    rtt.sort()
    return [
        Row("bus lockstep READ(2) transactions", reads, "1/s", ">= 50 000",
            "18 servos, 8 B out + 8 B back, in-process"),
        Row("bus lockstep WRITE(2) transactions", writes, "1/s", ">= 50 000", "6 B status back"),
        Row("bus virtual cycle, return delay 250", cycle_virtual_ms(250), "ms", "= 12.86",
            "18 READs + 98 B SYNC_WRITE: 18 x (80+500+80) + 980 us"),
        Row("bus virtual cycle, return delay 0", cycle_virtual_ms(0), "ms", "= 3.86",
            "18 x (80+80) + 980 us"),
        Row("bus pty READ round trip median", statistics.median(rtt) * 1e3, "ms", "<= 0.5",
            f"dynamixel-sdk, delay 0, {len(rtt)} ok; 160 us is wire time"),
        Row("bus pty READ round trip p90", rtt[int(0.9 * (len(rtt) - 1))] * 1e3, "ms", "", ""),
    ]
