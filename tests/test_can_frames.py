"""protocol/can_frames.py and protocol/hexhil.dbc describe the same frames, bit for bit."""
from __future__ import annotations

import random
from pathlib import Path

import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hexhil.protocol import can_frames as cf

DBC = Path(cf.__file__).with_name("hexhil.dbc")
DB = cantools.database.load_file(str(DBC))
NAMES = sorted(cf.FRAMES)

# The frames and signals docs/architecture.md promises to the other parts.
ARCHITECTURE = {
    "heartbeat": ("state", "fault_flags", "cycle", "overruns"),
    "tactile": ("switches", "overcoming", "step_counter"),
    "limit_switches": ("switches", "sequence"),
    "gait_command": ("command", "gait", "step_length_m", "step_height_m", "period_s"),
    "heading_command": ("direction_rad",),
    "force": ("fx_n", "fy_n", "fz_n", "sample"),
    "beam_estimate": ("k1_nm_per_rad", "k2_nm_per_rad", "hb_m", "mode"),
    "body_pose": ("x_m", "roll_rad", "pitch_rad"),
    "body_rate": ("vx_m_s", "roll_rate_rad_s", "pitch_rate_rad_s"),
    "actuator_command": ("fx_n", "tau1_nm", "tau2_nm"),
}


def test_frames_are_the_architecture_table() -> None:
    assert {n: cf.signals(n) for n in NAMES} == ARCHITECTURE
    assert sorted(m.name for m in DB.messages) == NAMES


@pytest.mark.parametrize("name", NAMES)
def test_dbc_layout_matches_module(name: str) -> None:
    arb_id, _, sigs = cf.FRAMES[name]
    msg = DB.get_message_by_name(name)
    assert msg.frame_id == arb_id and not msg.is_extended_frame
    assert msg.length == cf.DLC[name] <= 8
    assert [s.name for s in msg.signals] == [s[0] for s in sigs]
    for sname, kind, scale, lo, hi in sigs:
        s = msg.get_signal_by_name(sname)
        assert s.byte_order == "little_endian" and s.offset == 0
        assert s.scale == scale
        assert s.is_signed == (lo < 0)
        if kind == cf.SCALED:
            assert s.unit, f"{name}.{sname} has no unit in the DBC"
            assert s.minimum == pytest.approx(lo * scale) and s.maximum == pytest.approx(hi * scale)
        else:
            assert (s.minimum, s.maximum) == (lo, hi)
        assert s.comment, f"{name}.{sname} has no comment in the DBC"
    assert msg.comment


def test_dbc_value_tables_match_constants() -> None:
    def choices(frame: str, sig: str) -> dict[int, str]:
        s = DB.get_message_by_name(frame).get_signal_by_name(sig)
        return {int(k): str(v) for k, v in s.choices.items()}

    assert choices("heartbeat", "state") == dict(enumerate(cf.STATE_NAMES))
    assert cf.STATE_NAMES[cf.STATE_SAFE_STOP] == "safe_stop"
    assert choices("gait_command", "command") == dict(enumerate(cf.COMMAND_NAMES))
    assert choices("gait_command", "gait") == {cf.GAIT_TRIPOD: "tripod", cf.GAIT_WAVE: "wave"}
    assert choices("beam_estimate", "mode") == {cf.MODE_UNKNOWN: "unknown", cf.MODE_PITCH: "pitch",
                                                cf.MODE_ROLL: "roll"}


def _physical(sig: tuple, raw: int, frac: float) -> float | int:
    """An SI value that rounds to ``raw`` (``frac`` in -0.45..0.45 of a step off it)."""
    _, kind, scale, lo, hi = sig
    if kind != cf.SCALED:
        return raw
    v = (raw + frac) * scale
    return min(max(v, lo * scale), hi * scale)  # stay inside the DBC's [min|max]


def _agree_encode(name: str, values: dict) -> None:
    arb_id, data = cf.encode(name, **values)
    assert arb_id == DB.get_message_by_name(name).frame_id
    assert data == DB.encode_message(name, values), (name, values)
    # and back: both decoders read our bytes the same
    _agree_decode(arb_id, data)


def _agree_decode(arb_id: int, data: bytes) -> None:
    name, ours = cf.decode(arb_id, data)
    theirs = DB.decode_message(arb_id, data, decode_choices=False)
    assert ours == theirs, (name, data.hex())
    assert [type(v) for v in ours.values()] == [type(v) for v in theirs.values()]


def _random_values(rng: random.Random, name: str) -> dict:
    return {s[0]: _physical(s, rng.randint(s[3], s[4]), rng.uniform(-0.45, 0.45))
            for s in cf.FRAMES[name][2]}


@pytest.mark.parametrize("name", NAMES)
def test_cantools_agrees_over_random_values(name: str) -> None:
    rng = random.Random(name)
    arb_id = cf.FRAMES[name][0]
    for _ in range(300):
        _agree_encode(name, _random_values(rng, name))
        _agree_decode(arb_id, bytes(rng.getrandbits(8) for _ in range(cf.DLC[name])))
    # the ends of every range
    sigs = cf.FRAMES[name][2]
    _agree_encode(name, {s[0]: _physical(s, s[3], 0.0) for s in sigs})
    _agree_encode(name, {s[0]: _physical(s, s[4], 0.0) for s in sigs})


@st.composite
def _frame_values(draw: st.DrawFn) -> tuple[str, dict]:
    name = draw(st.sampled_from(NAMES))
    values = {}
    for s in cf.FRAMES[name][2]:
        raw = draw(st.integers(s[3], s[4]))
        values[s[0]] = _physical(s, raw, draw(st.floats(-0.45, 0.45)))
    return name, values


@settings(max_examples=300, deadline=None, derandomize=True)
@given(_frame_values())
def test_cantools_agrees_hypothesis_encode(case: tuple[str, dict]) -> None:
    _agree_encode(*case)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from(NAMES), st.binary(min_size=8, max_size=8))
def test_cantools_agrees_hypothesis_decode(name: str, data: bytes) -> None:
    _agree_decode(cf.FRAMES[name][0], data[:cf.DLC[name]])


def test_round_trip_within_half_a_step() -> None:
    values = dict(fx_n=1.23456, tau1_nm=-0.0987654, tau2_nm=0.1)
    _, out = cf.decode(*cf.encode("actuator_command", **values))
    assert out["fx_n"] == pytest.approx(1.23456, abs=0.5e-4)
    assert out["tau1_nm"] == pytest.approx(-0.0987654, abs=0.5e-5)
    assert out["tau2_nm"] == pytest.approx(0.1, abs=0.5e-5)


def test_scaled_signals_saturate_counters_wrap() -> None:
    _, out = cf.decode(*cf.encode("actuator_command", fx_n=50.0, tau1_nm=-9.0, tau2_nm=0.0))
    assert out["fx_n"] == pytest.approx(3.2767) and out["tau1_nm"] == pytest.approx(-0.32768)
    _, out = cf.decode(*cf.encode("force", fx_n=0, fy_n=0, fz_n=0, sample=65536 + 5))
    assert out["sample"] == 5
    _, out = cf.decode(*cf.encode("heartbeat", state=cf.STATE_WALKING,
                                  fault_flags=cf.FAULT_OVERRUN | cf.FAULT_OVERHEAT,
                                  cycle=2**32 + 1, overruns=3))
    assert out == {"state": 2, "fault_flags": 0x24, "cycle": 1, "overruns": 3}
    assert cf.faults_set(out["fault_flags"]) == ["overrun", "overheat"]


def test_bad_use_raises_value_error() -> None:
    with pytest.raises(ValueError, match="out of range"):
        cf.encode("heartbeat", state=6, fault_flags=0, cycle=0, overruns=0)
    with pytest.raises(ValueError, match="out of range"):
        cf.encode("tactile", switches=64, overcoming=0, step_counter=0)
    with pytest.raises(ValueError, match="missing signal overruns"):
        cf.encode("heartbeat", state=0, fault_flags=0, cycle=0)
    with pytest.raises(ValueError, match="no signal bogus"):
        cf.encode("heartbeat", state=0, fault_flags=0, cycle=0, overruns=0, bogus=1)
    with pytest.raises(ValueError, match="unknown CAN frame"):
        cf.encode("nope")
    with pytest.raises(ValueError, match="unknown CAN id 0x7FF"):
        cf.decode(0x7FF, bytes(8))
    with pytest.raises(ValueError, match="needs 6 bytes"):
        cf.decode(cf.ID_TACTILE, bytes(5))


def test_tactile_leg_bits() -> None:
    _, out = cf.decode(*cf.encode("tactile", switches=0b100001, overcoming=0b000100, step_counter=9))
    assert cf.legs_set(out["switches"]) == ["LF", "RH"]
    assert cf.legs_set(out["overcoming"]) == ["LH"]
    # the two unused high bits are ignored, as the DBC's 6-bit signal does
    assert cf.decode(cf.ID_TACTILE, bytes((0xFF, 0xC0, 0, 0, 0, 0)))[1]["switches"] == 0x3F


def test_python_can_message_round_trip() -> None:
    """The frames go onto a real python-can bus as standard-ID messages."""
    import can

    with can.Bus(interface="virtual", channel="hexhil-test-can-frames") as tx, \
            can.Bus(interface="virtual", channel="hexhil-test-can-frames") as rx:
        arb_id, data = cf.encode("gait_command", command=cf.COMMAND_START, gait=cf.GAIT_WAVE,
                                 step_length_m=0.06, step_height_m=0.03, period_s=1.2)
        tx.send(can.Message(arbitration_id=arb_id, data=data, is_extended_id=False))
        msg = rx.recv(timeout=1.0)
    assert msg is not None
    name, out = cf.decode(msg.arbitration_id, msg.data)
    assert name == "gait_command" and out["gait"] == cf.GAIT_WAVE
    assert out["step_length_m"] == pytest.approx(0.06) and out["period_s"] == pytest.approx(1.2)
