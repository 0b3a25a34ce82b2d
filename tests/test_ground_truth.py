"""What the run's ground truth hands the recorder: each servo's state as a row, which the
recorder takes as it takes a user's mapping."""
from __future__ import annotations


from hexhil.hil import scenario as scenario_mod
from hexhil.hil.run import rig
from hexhil.hil.seams import SERVO_STATE_FIELDS
from hexhil.trace import protobuf as pb
from hexhil.trace import recorder as rec
from conftest import ROOT


def test_a_servos_state_as_a_row_is_its_mapping(tmp_path):
    """The run hands the recorder each servo's state as a tuple (``state_row``), a user a
    mapping: the same message either way, and the servo's row in SERVO_STATE_FIELDS order."""
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    servos = rig.build(sc, world=rig.make_world(sc, 0)).bus.servos
    rows = [s.state_row() for s in servos]
    assert [r[0] for r in rows] == list(range(1, 19))
    maps = [dict(zip(SERVO_STATE_FIELDS, r)) for r in rows]
    assert [pb.servo_row(m) for m in maps] == rows
    files = []
    for states in (rows, maps):
        files.append(tmp_path / f"{len(files)}.mcap")
        with rec.Recorder(files[-1], {"seed": 1}, encode_in=rec.EncodeIn.THIS_PROCESS) as r:
            r.servo_state(100, states)
    assert files[0].read_bytes() == files[1].read_bytes()
