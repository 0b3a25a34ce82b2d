"""Seed 003's tactile rule is judged on the step after a press, and a step starts when the
foot leaves the ground: a switch that closes during the first centimetre
of a swing belongs to the next step, where the firmware (switched only at the start of a
step) applies it."""
import subprocess
import sys
from pathlib import Path

import pytest

from hexhil.expect import steps
from conftest import ROOT

LM = 1
# Measured: obstacles-low-small, seed 1, our firmware: leg LM's servo angles (rad) from
# /joints at 10 Hz from 59.928 s. Its switch closed at 60.908 s, while the foot was
# 6.7 mm up in a swing that had left the ground after 60.828 s; that swing (h 0.025 m,
# l 0.039 m) is the old one, the next, from 65.4 s, the changed one (h 0.065, l 0.098).
T0_S = 59.928
PRESS_S = 60.908
LM_JOINTS_RAD = [
    (0.09429, 0.42772, -0.19810),
    (0.10308, 0.42826, -0.19512),
    (0.10136, 0.44388, -0.20274),
    (0.10906, 0.44365, -0.19616),
    (0.11807, 0.44467, -0.19380),
    (0.12682, 0.44466, -0.19048),
    (0.13526, 0.44434, -0.18618),
    (0.14414, 0.44339, -0.18118),
    (0.15316, 0.44383, -0.17698),
    (0.16136, 0.44295, -0.17312),
    (0.14325, 0.52588, -0.27277),
    (0.12985, 0.65099, -0.35340),
    (0.11476, 0.73787, -0.40121),
    (0.10077, 0.76786, -0.41844),
    (0.07722, 0.74913, -0.40767),
    (0.00533, 0.67765, -0.35959),
    (-0.05610, 0.55028, -0.26364),
    (-0.07535, 0.43878, -0.17281),
    (-0.09077, 0.44361, -0.17349),
    (-0.08323, 0.44556, -0.17615),
    (-0.07983, 0.44659, -0.17605),
    (-0.07539, 0.44811, -0.17704),
    (-0.06927, 0.44944, -0.17793),
    (-0.07552, 0.44236, -0.17382),
    (-0.09281, 0.43310, -0.17069),
    (-0.10392, 0.42892, -0.17965),
    (-0.09487, 0.43188, -0.18573),
    (-0.08552, 0.43390, -0.18720),
    (-0.07724, 0.43550, -0.18841),
    (-0.06893, 0.43630, -0.18960),
    (-0.06050, 0.43663, -0.19076),
    (-0.05162, 0.43757, -0.19141),
    (-0.04461, 0.43627, -0.19170),
    (-0.05080, 0.42939, -0.19786),
    (-0.03407, 0.43104, -0.19469),
    (-0.02248, 0.43111, -0.19226),
    (-0.01118, 0.43131, -0.19197),
    (-0.00066, 0.43108, -0.19189),
    (0.00979, 0.43206, -0.19171),
    (0.01942, 0.43181, -0.19109),
    (0.02187, 0.43265, -0.19329),
    (0.01360, 0.42556, -0.20169),
    (0.03147, 0.42853, -0.19779),
    (0.04387, 0.42928, -0.19529),
    (0.05619, 0.43009, -0.19205),
    (0.06676, 0.43225, -0.19189),
    (0.07612, 0.43246, -0.19052),
    (0.08489, 0.43583, -0.18824),
    (0.08412, 0.44751, -0.19803),
    (0.08840, 0.45339, -0.19673),
    (0.09871, 0.45515, -0.19414),
    (0.10802, 0.45465, -0.18890),
    (0.11789, 0.45402, -0.18286),
    (0.12609, 0.45278, -0.17818),
    (0.13516, 0.45446, -0.17506),
    (0.14030, 0.43476, -0.16273),
    (0.10638, 0.64912, -0.35131),
    (0.01639, 0.96702, -0.50537),
    (-0.07008, 1.17611, -0.56445),
    (-0.15451, 1.24370, -0.56653),
    (-0.23871, 1.17485, -0.52541),
    (-0.31754, 0.97458, -0.43360),
    (-0.39397, 0.67775, -0.25972),
    (-0.45525, 0.38828, -0.03723),
    (-0.46837, 0.39422, -0.01953),
    (-0.43690, 0.39179, -0.03037),
    (-0.42586, 0.39743, -0.03679),
    (-0.41254, 0.40231, -0.04591),
    (-0.40193, 0.40752, -0.05463),
    (-0.38983, 0.41294, -0.06367),
    (-0.37615, 0.41679, -0.07233)
]


def _lm_steps() -> list[steps.Step]:
    times = [T0_S + 0.1 * i for i in range(len(LM_JOINTS_RAD))]
    samples = [(t, [0.0] * 3 * LM + list(q) + [0.0] * 3 * (5 - LM))
               for t, q in zip(times, LM_JOINTS_RAD)]
    return steps.steps(times, steps.foot_tracks(samples)[LM], LM, 0.0)


def test_lift_off_is_when_the_foot_leaves_the_ground_not_a_centimetre_up():
    first, second = _lm_steps()
    assert 60.828 < first.lift_off_s < PRESS_S    # already 6.7 mm up at 60.928 s
    assert 65.428 < second.lift_off_s < 65.528     # on the ground, then 15.6 mm up


def test_a_press_during_the_first_centimetre_of_a_swing_judges_the_next_step():
    lm = _lm_steps()
    press = steps.Press(LM, PRESS_S, 1.5)
    (judged,) = steps.steps_after_presses(lm, [press], 0.02, 0.0, 70.0)
    assert judged == lm[1]
    assert judged.height_m == pytest.approx(0.065, abs=0.003)
    assert judged.length_m == pytest.approx(0.099, abs=0.003)


def _case(tmp_path: Path, seed: int) -> Path:
    src = (ROOT / "tests" / "firmware" / "tactile-low-small.toml").read_text()
    case = tmp_path / f"low-small-90s-seed{seed}.toml"
    case.write_text(src.replace('"../../scenarios/', f'"{ROOT}/scenarios/')
                    .replace("duration_s = 40", f"duration_s = 90\nseed = {seed}"))
    return case


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_our_firmware_keeps_the_rule_over_the_whole_obstacles_low_small(tmp_path, seed):
    """The full 90 s of obstacles-low-small, seeds 1-3: the rule holds, and fails with it off."""
    def judge(*extra: str) -> str:
        proc = subprocess.run([sys.executable, "-m", "hexhil.cli", "test",
                               str(_case(tmp_path, seed)), "--python", "cpython-inprocess",
                               *extra], cwd=ROOT, capture_output=True, text=True, timeout=900)
        return next(line for line in proc.stdout.splitlines() if "tactile rule" in line)
    assert judge().rstrip().endswith("pass")
    assert judge("--no-tactile").rstrip().endswith("FAIL")
