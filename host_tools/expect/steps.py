"""Seed 003's tactile rule measured from the recorded joints: each leg's steps (lift-off,
height, length) through the robot description's forward kinematics, and the switch presses
that must change the next step (Eq. 6: l_k = 2 l_i; Eq. 7: h_k = H + 2 cm).

Measured from ``/joints`` (ground truth at 10 Hz), never from the firmware's telemetry, so a
firmware that reports the rule but does not move the legs fails. The foot is placed in the
body frame by ``protocol/hexapod.py`` (``Leg.joint_rad`` then ``Leg.fk``). A step is a run of
samples with the foot more than ``SWING_THRESHOLD_M`` above the leg's stance level (its
median height); its height is the highest sample above that level, its length the foot's
travel along the walking direction from the rearmost sample just before the swing to the
foremost just after it (the stance moves the foot back, the swing forward).

Its lift-off is when the foot left the ground, not when it passed the threshold: the rise
into the swing is followed back to the last sample on the ground (the foot rose less than
``RISE_M`` from the one before), and the moment between that sample and the first one up
is where the line through the first two samples up meets the ground sample's height. A
switch that closes during the first centimetre of a swing (LM at 60.9 s of
obstacles-low-small) is after this lift-off, so the rule is judged on the next step, as
the firmware (switched only at the start of a step) applies it.
"""
from __future__ import annotations

import math
import statistics
from dataclasses import dataclass
from typing import Sequence

from hexhil.protocol import hexapod

STEP_FACTOR = 2.0            # Eq. 6: l_k = 2 l_i
OBSTACLE_CLEARANCE_M = 0.02  # Eq. 7: h_k = H + 2 cm
SWING_THRESHOLD_M = 0.01     # above the stance level: the foot is in the air
EDGE_SAMPLES = 4             # samples either side of a swing searched for its ends
RISE_M = 0.002               # a sample this much above the one before: the foot is rising


@dataclass(frozen=True)
class Step:
    leg: int
    lift_off_s: float      # when the foot left the ground (module docstring)
    touch_down_s: float
    height_m: float
    length_m: float


@dataclass(frozen=True)
class Press:
    leg: int
    t_s: float
    held_s: float


def foot_tracks(joint_samples: Sequence[tuple[float, Sequence[float]]]
                ) -> list[list[tuple[float, float, float]]]:
    """Per leg, the foot (x, y, z) in the body frame at each sample of servo angles (rad,
    servo-ID order, as ``/joints`` holds them)."""
    legs = [hexapod.Leg(i) for i in range(len(hexapod.LEGS))]
    tracks: list[list[tuple[float, float, float]]] = [[] for _ in legs]
    for _, q in joint_samples:
        for i, leg in enumerate(legs):
            joints = [leg.joint_rad(j, q[3 * i + j]) for j in range(3)]
            tracks[i].append(leg.fk(*joints))
    return tracks


def steps(times_s: Sequence[float], track: Sequence[tuple[float, float, float]], leg: int,
          direction_rad: float) -> list[Step]:
    """The swings of one leg's foot track (see the module docstring)."""
    if not track:
        return []
    ground = statistics.median(p[2] for p in track)
    along = [p[0] * math.cos(direction_rad) + p[1] * math.sin(direction_rad) for p in track]
    n = len(track)
    out: list[Step] = []
    k = 0
    while k < n:
        if track[k][2] - ground <= SWING_THRESHOLD_M:
            k += 1
            continue
        a = k
        while k < n and track[k][2] - ground > SWING_THRESHOLD_M:
            k += 1
        b = k - 1
        if a == 0 or k == n:  # cut by the recording's ends: not a whole step
            continue
        rear = min(along[max(0, a - EDGE_SAMPLES):a + 1])
        front = max(along[b:min(n, b + 1 + EDGE_SAMPLES)])
        height = max(p[2] for p in track[a:b + 1]) - ground
        out.append(Step(leg, _lift_off_s(times_s, track, a), times_s[k], height, front - rear))
    return out


def _lift_off_s(times_s: Sequence[float], track: Sequence[tuple[float, float, float]],
                a: int) -> float:
    """When the foot left the ground in the rise to sample ``a`` (the first above the
    threshold; sample ``a - 1`` exists)."""
    g = a - 1
    while g > 0 and track[g][2] - track[g - 1][2] > RISE_M:
        g -= 1
    up = g + 1               # the first sample off the ground (a at the latest)
    t0, t1 = times_s[g], times_s[up]
    z0, z1 = track[g][2], track[up][2]
    if up + 1 >= len(track) or track[up + 1][2] <= z1:
        return t0
    slope = (track[up + 1][2] - z1) / (times_s[up + 1] - t1)
    return min(t1, max(t0, t1 - (z1 - z0) / slope))


def presses(edges: Sequence[tuple[float, int, bool]], end_s: float) -> list[Press]:
    """Switch presses (rising edges) with how long each was held, from (t, leg, level)."""
    out: list[Press] = []
    down: dict[int, float] = {}
    for t, leg, level in edges:
        if level:
            down.setdefault(leg, t)
        elif leg in down:
            t0 = down.pop(leg)
            out.append(Press(leg, t0, t - t0))
    out.extend(Press(leg, t0, end_s - t0) for leg, t0 in down.items())
    return sorted(out, key=lambda p: p.t_s)


def steps_after_presses(all_steps: Sequence[Step], all_presses: Sequence[Press],
                        min_press_s: float, start_s: float, end_s: float) -> list[Step]:
    """Each leg's next step after a press that lasted ``min_press_s`` (the firmware
    debounces), the press and the lift-off both inside [start_s, end_s]; one step however
    many presses came before it."""
    out: list[Step] = []
    for leg in sorted({s.leg for s in all_steps}):
        mine = [s for s in all_steps if s.leg == leg]
        for p in all_presses:
            if p.leg != leg or p.held_s < min_press_s or not start_s <= p.t_s <= end_s:
                continue
            nxt = next((s for s in mine if s.lift_off_s >= p.t_s), None)
            if nxt is not None and nxt.lift_off_s <= end_s and nxt not in out:
                out.append(nxt)
    return sorted(out, key=lambda s: s.lift_off_s)
