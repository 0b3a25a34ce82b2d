"""docs/servo-bus.md's quick reference says what the code does: the ID -> leg and joint
table and neutral stance from the robot description (protocol/hexapod.py), the addresses
from protocol/dynamixel/ax12.py, and the signs from the legs' forward kinematics."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from hexhil.protocol import hexapod
from hexhil.protocol.dynamixel import ax12

DOC = (Path(__file__).resolve().parent.parent / "docs" / "servo-bus.md").read_text()
QUICK = DOC.split("## Quick reference", 1)[1].split("\n## ", 1)[0]


def _rows(header: str) -> list[list[str]]:
    """The cells of the quick reference's table whose header row starts with ``header``."""
    block = QUICK.split(f"\n| {header} |", 1)[1].split("\n\n", 1)[0]
    return [[c.strip() for c in line.strip("|").split("|")]
            for line in block.splitlines()[2:] if line.startswith("|")]


def test_the_quick_reference_is_near_the_top():
    assert DOC.index("## Quick reference") < DOC.index("## Serving servos")


def test_ids_legs_joints_and_neutral_stance_match_the_robot_description():
    rows = _rows("ID")
    assert len(rows) == hexapod.SERVOS
    for leg_i, name in enumerate(hexapod.LEGS):
        leg = hexapod.Leg(leg_i)
        q = leg.ik(*hexapod.neutral_foot(leg_i))
        for j, joint in enumerate(hexapod.JOINTS):
            dev_id = 3 * leg_i + j + 1
            units = ax12.rad_to_position(leg.servo_rad(j, q[j]))
            assert rows[dev_id - 1] == [str(dev_id), name, joint, str(units)]


def test_addresses_sizes_and_access_match_the_control_table():
    rows = _rows("address")
    assert {"Torque Enable", "Goal Position", "Moving Speed", "Present Position"} <= \
        {r[1] for r in rows}
    for address, name, size, access, _ in rows:
        field = ax12.BY_NAME[name.lower().replace(" ", "_")]
        assert (field[0], field[2], field[3]) == (int(address), int(size), access), name
    assert ax12.defaults()[ax12.TORQUE_ENABLE] == 0 and "Torque Enable 0" in QUICK


SIGN_WORDS = {"coxa": "counter-clockwise seen from above", "femur": "the foot rises",
              "tibia": "the foot swings out and up"}


@pytest.mark.parametrize("leg_i", range(len(hexapod.LEGS)), ids=hexapod.LEGS)
def test_a_higher_goal_position_moves_each_leg_as_the_signs_table_says(leg_i):
    assert {r[0]: r[1] for r in _rows("joint")}.keys() == SIGN_WORDS.keys()
    for joint, words in SIGN_WORDS.items():
        assert words in dict(_rows("joint"))[joint]
    leg = hexapod.Leg(leg_i)
    q = list(leg.ik(*hexapod.neutral_foot(leg_i)))
    one_unit = math.radians(ax12.POSITION_RANGE_DEG / ax12.POSITION_MAX)

    def foot_after(j: int) -> tuple[float, float, float]:
        moved = list(q)
        moved[j] = leg.joint_rad(j, leg.servo_rad(j, q[j]) + 10 * one_unit)
        return leg.fk(*moved)

    x0, y0, z0 = leg.fk(*q)
    mx, my, _ = hexapod.MOUNTS[leg_i]
    x, y, _ = foot_after(0)                       # coxa: counter-clockwise about z (up)
    assert (x0 - mx) * (y - my) - (y0 - my) * (x - mx) > 0
    assert foot_after(1)[2] > z0                  # femur: the foot rises
    x, y, z = foot_after(2)                       # tibia: out and up
    assert z > z0 and math.hypot(x - mx, y - my) > math.hypot(x0 - mx, y0 - my)
