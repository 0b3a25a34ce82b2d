"""A user's MicroPython firmware for the hexapod's STM32F411 board: only ``machine``,
``time`` and the wiring table of docs/your-firmware.md (no hexhil code).

It pings the 18 AX-12 servos (Protocol 1.0 packets built here), moves one and reads it
back, reads the six limit switches, then walks a simple tripod gait forward until the
simulator ends the run. On the virtual board:

    hexhil run scenarios/flat-tripod.toml --firmware examples/board_tripod.py

On the real board it is ``main.py``. Set ``RAISE_DIRECTION = False`` to see the classic
half-duplex mistake: the transmit buffer never opens, so no servo ever answers.
"""
import math
import time

from machine import Pin, UART

RAISE_DIRECTION = True

# --- wiring (docs/your-firmware.md) ---------------------------------------------------
uart = UART(2, baudrate=1000000, timeout=2, timeout_char=1)
direction = Pin("A1", Pin.OUT, value=0)          # high: transmit, low: receive
switches = [Pin(n, Pin.IN, Pin.PULL_UP) for n in ("B0", "B1", "B2", "B3", "B4", "B5")]

# --- AX-12, Protocol 1.0 ------------------------------------------------------------
PING, READ, WRITE, SYNC_WRITE = 1, 2, 3, 0x83
BROADCAST = 254
TORQUE_ENABLE, GOAL_POSITION, PRESENT_POSITION = 24, 30, 36


def packet(dev_id, instruction, params=b""):
    body = bytes((dev_id, len(params) + 2, instruction)) + params
    return b"\xff\xff" + body + bytes(((~sum(body)) & 0xFF,))


def send(data):
    if RAISE_DIRECTION:
        direction.value(1)
    uart.write(data)
    uart.flush()               # wait until the last stop bit has left
    direction.value(0)


def request(dev_id, instruction, params=b"", nparams=0):
    """Send a packet and read the status (6 + nparams bytes); its parameters or None."""
    send(packet(dev_id, instruction, params))
    status = uart.read(6 + nparams)
    if status is None or len(status) < 6 + nparams or status[2] != dev_id:
        return None
    return status[5:5 + nparams]


# --- the robot (docs/your-firmware.md "The robot") ----------------------------------
COXA, FEMUR, TIBIA = 0.05, 0.082, 0.12
D45 = math.pi / 4
MOUNTS = ((0.10, 0.06, D45), (0.0, 0.075, 2 * D45), (-0.10, 0.06, 3 * D45),
          (0.10, -0.06, -D45), (0.0, -0.075, -2 * D45), (-0.10, -0.06, -3 * D45))
REACH, DEPTH = 0.15, 0.085          # neutral foot: along the mount, this far below the coxa
TIBIA_ZERO = -math.pi / 2           # tibia angle at the servo's centre
STEP, LIFT, PERIOD_S, CYCLE_MS = 0.05, 0.03, 2.0, 20
TRIPOD_A = (0, 2, 4)                # LF, LH, RM swing in the first half; LM, RF, RH then


def position(angle_rad):
    """Servo angle (0 at the centre) -> goal position, 1023 units over 300 deg."""
    v = int(round((math.degrees(angle_rad) + 150.0) * 1023 / 300.0))
    return max(0, min(1023, v))


def leg_positions(leg, x, y, z):
    """Goal positions (coxa, femur, tibia) for the foot at body-frame (x, y, z)."""
    mx, my, yaw = MOUNTS[leg]
    dx, dy = x - mx, y - my
    lx = math.cos(yaw) * dx + math.sin(yaw) * dy
    ly = -math.sin(yaw) * dx + math.cos(yaw) * dy
    q1 = math.atan2(ly, lx)
    r = math.sqrt(lx * lx + ly * ly) - COXA
    d = math.sqrt(r * r + z * z)
    a = (FEMUR * FEMUR + d * d - TIBIA * TIBIA) / (2 * FEMUR * d)
    b = (FEMUR * FEMUR + TIBIA * TIBIA - d * d) / (2 * FEMUR * TIBIA)
    q2 = math.atan2(z, r) + math.acos(max(-1.0, min(1.0, a)))
    q3 = math.acos(max(-1.0, min(1.0, b))) - math.pi
    return position(q1), position(q2), position(q3 - TIBIA_ZERO)


def foot(leg, phase):
    """Foot target at gait phase 0..1: half the period on the ground moving back, half
    in the air moving forward."""
    mx, my, yaw = MOUNTS[leg]
    x0, y0 = mx + REACH * math.cos(yaw), my + REACH * math.sin(yaw)
    p = (phase + (0.5 if leg in TRIPOD_A else 0.0)) % 1.0
    if p < 0.5:                      # swing: from -STEP/2 to +STEP/2, lifted
        s = p / 0.5
        return x0 + STEP * (s - 0.5), y0, -DEPTH + LIFT * math.sin(math.pi * s)
    s = (p - 0.5) / 0.5              # stance: from +STEP/2 back to -STEP/2
    return x0 + STEP * (0.5 - s), y0, -DEPTH


def goals(phase):
    params = bytearray((GOAL_POSITION, 2))
    for leg in range(6):
        for j, v in enumerate(leg_positions(leg, *foot(leg, phase))):
            params += bytes((3 * leg + j + 1, v & 0xFF, v >> 8))
    return bytes(params)


def main():
    found = [i for i in range(1, 19) if request(i, PING) is not None]
    print("ping: %d servos answer: %s" % (len(found), found))
    send(packet(BROADCAST, WRITE, bytes((TORQUE_ENABLE, 1))))
    send(packet(BROADCAST, SYNC_WRITE, goals(0.0)))          # neutral stance
    time.sleep_ms(500)
    start = request(1, READ, bytes((PRESENT_POSITION, 2)), 2)
    request(1, WRITE, bytes((GOAL_POSITION, 0x20, 0x02)))    # servo 1 to 544
    time.sleep_ms(300)
    moved = request(1, READ, bytes((PRESENT_POSITION, 2)), 2)
    print("servo 1 moved from %s to %s" % (start and start[0] | start[1] << 8,
                                           moved and moved[0] | moved[1] << 8))
    print("switches pressed:", [1 - s.value() for s in switches])
    t = time.ticks_ms()
    cycles = 0
    while True:
        phase = (cycles * CYCLE_MS / 1000.0 / PERIOD_S) % 1.0
        send(packet(BROADCAST, SYNC_WRITE, goals(phase)))
        cycles += 1
        t = time.ticks_add(t, CYCLE_MS)
        wait = time.ticks_diff(t, time.ticks_ms())
        if wait > 0:
            time.sleep_ms(wait)


main()
