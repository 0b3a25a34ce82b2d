"""A whole line's SYNC_WRITE and READ in one compiled call (hil/servobus/servo_core.c)
leave every servo as its own ``handle`` does, servo by servo, with the same rules
(servo_rules.py): what the one call adds is the dispatch (which servos it serves, in
what order, and the ones it hands back). Runs of the shipped firmware on the
hexapod world (with the fault vocabulary that reaches a servo's state: overheating, a
supply sag, a stall, an overload, a brown-out, an unplugged servo) and a scripted master's
SYNC_WRITEs and READs (torque limits, compliance, Lock, EEPROM writes, wheel mode, refused
values, Status Return Levels) give the same serial bytes, control tables, servo and health
fields and drive-bank arrays, to the bit. Built by `make` (the pinned ziglang's cc); these
tests fail if it is missing, so the build is checked."""
from __future__ import annotations

import ctypes
import random

import numpy as np
import pytest

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run.rig import make_world
from hexhil.hil.servobus import servo_core
from hexhil.hil.servobus.switch_node import SensorNode
from hexhil.in_process import run_firmware
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from conftest import ROOT

NODE_ID = 100   # the limit-switch node's (hil/servobus/switch_node.py)
FAULTS = {"overheat": [{"id": 2, "at_s": 0.5, "until_s": 2.5, "temperature_c": 90.0}],
          "voltage_sag": [{"at_s": 1.0, "until_s": 1.6, "volts": 6.5}],
          "stall": [{"id": 8, "at_s": 0.8, "until_s": 2.0}],
          "overload": [{"id": 11, "at_s": 1.2}],
          "brownout": [{"id": 4, "at_s": 1.5}],
          "unplug": [{"id": 16, "at_s": 2.0, "until_s": 2.4}]}


def _state(sim: Simulator) -> bytes:
    """Everything a SYNC_WRITE can change: tables, the servos' and their health's fields,
    the world's drive bank."""
    out = bytearray()
    for s in sim.bus.servos:
        out += bytes(s.table)
        if not isinstance(s, ctypes.Structure):   # the switch node
            continue
        out += ctypes.string_at(ctypes.addressof(s), ctypes.sizeof(s))
        out += ctypes.string_at(ctypes.addressof(s.health), ctypes.sizeof(s.health))
    arrays = [a for a in vars(sim.world.drives).values() if isinstance(a, np.ndarray)]
    assert len(arrays) >= 10   # goal, set-point, speed, torque, enabled, compliance, duty ...
    for a in arrays:
        out += a.tobytes()
    return bytes(out)


def _sim(overlay: dict | None, compiled: bool, monkeypatch, node: bool = False) -> Simulator:
    monkeypatch.setattr(servo_core, "_LIB", servo_core._load() if compiled else None)
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    if overlay:
        sc = sc.overlay(overlay)
    sim = Simulator(sc, 1, world=make_world(sc, 1))
    if node:
        sim.bus.add_device(SensorNode(lambda: 0b101001, NODE_ID))
    assert (sim.bus.servo_bank is not None) == compiled
    return sim


def test_the_library_is_built():
    assert servo_core.available(), f"{servo_core.LIBRARY} missing: run make"


@pytest.mark.parametrize("overlay", [None, {"faults": FAULTS}], ids=["plain", "faults"])
def test_a_run_is_the_same_with_and_without_the_compiled_servos(overlay, monkeypatch):
    runs = []
    for compiled in (True, False):
        sim = _sim(overlay, compiled, monkeypatch)
        r = sim.run(3.0, in_process=run_firmware)
        runs.append((r.serial_digest, r.cycles, _state(sim)))
    assert runs[0][1] > 100
    assert runs[0] == runs[1]


def _traffic(rng: random.Random, k: int) -> bytes:
    """A scripted SYNC_WRITE: mostly goals and speeds, sometimes other fields; an EEPROM
    write is followed by goals at once."""
    ids = list(range(1, 19))
    choice = k % 9
    if choice == 3:    # torque limit, sometimes 0 or out of range
        addr, n = ax12.TORQUE_LIMIT, 2
        vals = [rng.choice([0, 300, 1023, 1100]) for _ in ids]
    elif choice == 5:  # compliance margins and slopes, then punch
        addr, n = ax12.CW_COMPLIANCE_MARGIN, 4
        vals = [rng.randrange(1 << 32) & 0x40207F03 for _ in ids]
    elif choice == 6:  # torque off/on, punch, or Lock (late: it ends the EEPROM writes)
        addr, n = rng.choice([(ax12.TORQUE_ENABLE, 1), (ax12.PUNCH, 2)]
                             + [(ax12.LOCK, 1)] * (k > 300))
        vals = [rng.choice([0, 1, 40]) for _ in ids]
    elif choice == 7:  # angle limits: wheel mode or EEPROM busy; a malformed packet
        addr, n = ax12.CW_ANGLE_LIMIT, 4
        vals = [rng.choice([0, 1023 << 16, (200 | (800 << 16))]) for _ in ids]
        if k % 2:
            return dxl.packet(dxl.BROADCAST_ID, dxl.SYNC_WRITE, bytes([addr, n, 1, 2]))
    else:              # goal and speed, wheel speeds over 1023 included
        addr, n = ax12.GOAL_POSITION, 4
        vals = [rng.randrange(1024) | (rng.choice([0, 100, 1023, 1500]) << 16) for _ in ids]
    rng.shuffle(ids)
    entries = [(i, v.to_bytes(4, "little")[:n]) for i, v in zip(ids, vals)][:rng.randrange(19)]
    packet = dxl.sync_write(addr, n, entries)
    if choice == 7:   # goals in the same burst: the servos that took it are still busy
        return packet + _traffic(rng, k + 1)
    return packet


def test_scripted_sync_writes_leave_the_same_state(monkeypatch):
    """Each packet's effect compared: the line's replies to a READ after it (the whole
    table, the Present registers, refused ranges; at each Status Return Level), and the
    whole state. The limit-switch node shares the line (hexhil bus --world): a device the
    C code leaves to its own ``handle``, in the line's order."""
    sims = [_sim(None, compiled, monkeypatch, node=True) for compiled in (True, False)]
    rngs = [random.Random(5), random.Random(5)]
    for k in range(400):
        states = []
        for sim, rng in zip(sims, rngs):
            bus = sim.bus
            bus.master_write(_traffic(rng, k))
            dev = (1 + k % 18) if k % 5 else NODE_ID
            if k % 50 == 10:   # Status Return Level 0, 1 or 2: a READ answered or not
                bus.master_write(dxl.write(dev, ax12.STATUS_RETURN_LEVEL, bytes([k % 3])))
                bus.master_read(6, 5000)
            a, n = ((0, ax12.TABLE_SIZE), (36, 6), (45, 8), (10, 0))[k % 4]   # two refused
            bus.master_write(dxl.read(dev, a, n))
            rx = bus.master_read(ax12.TABLE_SIZE + 6, 5000)
            bus.idle_until(bus.clock.t_us + 3000 + 1000 * (k % 7))
            states.append((rx, _state(sim)))
        assert states[0] == states[1], k


@pytest.mark.parametrize("address", [ax12.ID, ax12.BAUD_RATE])
def test_a_sync_write_to_an_id_or_baud_rate_reindexes_the_line(address, monkeypatch):
    """Servo 1 given ID 30 (or another baud) by a broadcast SYNC_WRITE: in C as in Python
    the line re-indexes at once, so a READ to 30 is answered and one to 1 is not."""
    heard = []
    for compiled in (True, False):
        sim = _sim(None, compiled, monkeypatch)
        bus = sim.bus
        value = 30 if address == ax12.ID else 3   # 3: 500 kbps
        bus.master_write(dxl.sync_write(address, 1, [(1, bytes([value]))]))
        bus.idle_until(bus.clock.t_us + 20_000)   # the EEPROM write done
        replies = []
        for dev in (30, 1, 2):
            bus.master_write(dxl.read(dev, ax12.PRESENT_POSITION, 2))
            replies.append(bus.master_read(8, 5000))
            bus.idle_until(bus.clock.t_us + 2000)
        heard.append(replies)
    assert heard[0] == heard[1]
    to_30, to_1, to_2 = heard[0]
    assert len(to_2) == 8
    if address == ax12.ID:
        assert len(to_30) == 8 and to_30[2] == 30 and to_1 == b""
    else:
        assert to_30 == b"" and to_1 == b""   # servo 1 listens at 500 kbps now


def test_the_ground_truth_rows_are_the_servos_own(monkeypatch, tmp_path):
    """``hx_state_rows`` (a 10 Hz ground-truth sample in one call) gives what each servo's
    ``state_row`` gives, to the bit and the type (their reprs), through the fault
    vocabulary: error bits of each kind, torque off, moving and still."""
    from hexhil.trace.recorder import Recorder

    seen = []
    rows_of = servo_core.ServoBank.state_rows

    def both(self, servos):
        rows = rows_of(self, servos)
        seen.append((repr(list(rows)), repr([s.state_row() for s in servos]), list(rows)))
        return rows
    monkeypatch.setattr(servo_core.ServoBank, "state_rows", both)
    sag = [{"at_s": 1.0, "until_s": 1.6, "volts": 5.5}]   # under the 6 V limit: an error bit
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml").overlay(
        {"faults": {**FAULTS, "voltage_sag": sag}})
    with Recorder(tmp_path / "t.mcap") as rec:
        sim = Simulator(sc, 1, world=make_world(sc, 1), recorder=rec)
        sim.run(3.0, in_process=run_firmware)
        rec.close()
    assert len(seen) >= 29
    assert all(compiled == python for compiled, python, _ in seen)
    rows = [r for *_, sample in seen for r in sample]
    for bit in (dxl.ERR_INPUT_VOLTAGE, dxl.ERR_OVERHEATING, dxl.ERR_OVERLOAD):
        assert any(r[8] & bit for r in rows), bit
    assert {r[6] for r in rows} == {r[7] for r in rows} == {True, False}
