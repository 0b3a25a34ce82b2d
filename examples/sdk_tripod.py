"""A foreign firmware: walk the simulated hexapod forward with a tripod gait through the
stock ROBOTIS ``dynamixel-sdk`` alone (PortHandler, PacketHandler, GroupSyncWrite, reads).

    hexhil bus --world scenarios/flat-tripod.toml --duration 40     # prints "pty: /dev/pts/N"
    python examples/sdk_tripod.py /dev/pts/N --seconds 30

The leg geometry (IK, neutral stance) comes from protocol/hexapod.py, the robot's
description; the bus is only the SDK's. Each 20 ms cycle: one GroupSyncWrite of goal
position + moving speed to the 18 servos, one read of the limit-switch sensor node
(ID 100, address 26; docs/servo-bus.md).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import dynamixel_sdk as sdk

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from hexhil.protocol import hexapod  # noqa: E402  (the robot's geometry, not a bus master)

GOAL_POSITION, TORQUE_ENABLE, SWITCHES = 30, 24, 26
SENSOR_ID = 100
PERIOD_S = 2.0         # one tripod cycle: each group swings for half of it
STEP_M = 0.05          # foot travel along x per step
LIFT_M = 0.03
CYCLE_S = 0.02
GROUP_A = (0, 2, 4)    # LF, LH, RM swing together; LM, RF, RH in the other half


def position(rad: float) -> int:
    """AX-12 goal (0-1023 over 300 degrees, 512 at the centre)."""
    return max(0, min(1023, round(512 + rad * 1023 / math.radians(300))))


def foot(leg: int, t_s: float) -> tuple[float, float, float]:
    """Tripod foot target in the body frame: swing forward lifted, stance back on the ground."""
    phase = (t_s / PERIOD_S + (0.0 if leg in GROUP_A else 0.5)) % 1.0
    x, y, z = hexapod.neutral_foot(leg)
    if phase < 0.5:                       # swing: -STEP/2 -> +STEP/2, lifted
        u = phase / 0.5
        return x + STEP_M * (u - 0.5), y, z + LIFT_M * math.sin(math.pi * u)
    u = (phase - 0.5) / 0.5               # stance: +STEP/2 -> -STEP/2 pushes the body forward
    return x + STEP_M * (0.5 - u), y, z


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("port", help="the rig's pty or serial device")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--baud", type=int, default=1_000_000)
    a = ap.parse_args()
    port, ph = sdk.PortHandler(a.port), sdk.PacketHandler(1.0)
    if not port.openPort() or not port.setBaudRate(a.baud):
        print(f"cannot open {a.port}", file=sys.stderr)
        return 2
    model, result, _ = ph.ping(port, SENSOR_ID)
    sensor = result == sdk.COMM_SUCCESS
    print(f"sensor node: {'model 0x%04X' % model if sensor else 'absent'}")
    for dev in range(1, 19):
        if ph.write1ByteTxRx(port, dev, TORQUE_ENABLE, 1)[0] != sdk.COMM_SUCCESS:
            print(f"servo {dev} did not answer", file=sys.stderr)
            return 1
    legs = [hexapod.Leg(i) for i in range(6)]
    sync = sdk.GroupSyncWrite(port, ph, GOAL_POSITION, 4)
    last = [512] * 18
    t0 = time.monotonic()
    cycles, presses, switches = 0, 0, 0
    while (t := time.monotonic() - t0) < a.seconds:
        sync.clearParam()
        for i, leg in enumerate(legs):
            q = leg.ik(*foot(i, t))
            for j in range(3):
                k = 3 * i + j
                pos = position(leg.servo_rad(j, q[j]))
                speed = max(1, min(1023, round(abs(pos - last[k]) / CYCLE_S * 60 / 1023 * 300 / 360 / 0.111 * 1.5)))
                last[k] = pos
                sync.addParam(k + 1, bytes((pos & 0xFF, pos >> 8, speed & 0xFF, speed >> 8)))
        sync.txPacket()
        if sensor:
            bits, result, _ = ph.read1ByteTxRx(port, SENSOR_ID, SWITCHES)
            if result == sdk.COMM_SUCCESS:
                presses += bin(bits & ~switches).count("1")
                switches = bits
        cycles += 1
        time.sleep(max(0.0, t0 + cycles * CYCLE_S - time.monotonic()))
    port.closePort()
    print(f"{cycles} cycles in {a.seconds:.0f} s, {presses} switch presses")
    return 0


if __name__ == "__main__":
    sys.exit(main())
