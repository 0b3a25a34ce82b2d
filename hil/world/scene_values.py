"""The values a world's 3D scene is made of (hil/world/scene.py makes them; the recorder
turns them into Foxglove's messages): shapes, frames and arrows as NamedTuples, and two
samples held as the raw values they follow from.

``JointFrames`` and ``ContactForces`` are what the hexapod's ground truth hands the
recorder each 10 Hz sample: the joint coordinates, and the contacts as MuJoCo gave them.
The poses and the sums are made when first read, which the recorder does where it
encodes (its child process, or while the firmware computes), off the run's cycle: the
same arithmetic in the same order, so the same values wherever it runs. No numpy or
MuJoCo here: the recorder imports this module.
"""
from __future__ import annotations

import math
import struct
from typing import Any, NamedTuple

from hexhil.hil.seams import HeldSample

_F32 = [struct.Struct(f"<{n}f") for n in range(8)]


class Shape(NamedTuple):
    """One primitive: ``kind`` cube | cylinder (along z) | sphere (an ellipsoid when the
    sizes differ); ``size_m`` its full extents; pose in ``frame``."""

    id: str
    frame: str
    kind: str
    position_m: tuple[float, float, float]
    quat_wxyz: tuple[float, float, float, float]
    size_m: tuple[float, float, float]
    rgba: tuple[float, float, float, float]


class Frame(NamedTuple):
    """A moving frame's pose in its ``parent`` frame."""

    id: str
    parent: str
    position_m: tuple[float, float, float]
    quat_wxyz: tuple[float, float, float, float]


class Arrow(NamedTuple):
    """A force (N) acting at a point (m), both in ``world``."""

    id: str
    origin_m: tuple[float, float, float]
    force_n: tuple[float, float, float]


def f32_tuple(v: Any) -> tuple[float, ...]:
    """Floats rounded to float32: the scene is for looking at (0.1 um at 1 m), and the
    zeroed low bits let zstd pack the 10 Hz poses and forces to about half."""
    fmt = _F32[len(v)]
    return fmt.unpack(fmt.pack(*v))   # numpy's floats and ints pack as their float()


class JointFrames(HeldSample[Frame]):
    """A sample's moving frames, held as the joint coordinates they follow from:
    ``JointFrames(bodies, qpos)``, ``bodies`` the model's constant table
    (hil/world/scene.py ``ModelScene``). The recorder holds it as it is and reads it where
    it encodes (the encoding child, or while the firmware computes), so a sample costs the
    run a copy of ``qpos``, not 19 poses.

    A free body's pose is in ``world``, a body on one hinge in its parent's (the model's
    fixed offset turned by the joint angle), as ``/body`` and ``/joints`` have them.
    Relative poses keep the constant parts exact zeros or constants, which protobuf leaves
    out or zstd packs."""

    @staticmethod
    def _make(bodies: tuple, qpos: list[float]) -> list[Frame]:
        out = []
        for name, parent, adr, free, pos, (w1, x1, y1, z1), (ax, ay, az) in bodies:
            if free:  # a free joint: position, then the quaternion
                out.append(Frame(name, parent, f32_tuple(qpos[adr:adr + 3]),
                                 f32_tuple(qpos[adr + 3:adr + 7])))
                continue
            half = qpos[adr] / 2
            s = math.sin(half)
            w2, x2, y2, z2 = math.cos(half), s * ax, s * ay, s * az
            quat = (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2 + 0.0,   # no -0.0
                    w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2 + 0.0,
                    w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2 + 0.0,
                    w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2 + 0.0)
            out.append(Frame(name, parent, pos, f32_tuple(quat)))
        return out


class ContactForces(HeldSample[Arrow]):
    """The summed contact force on each geom of ``geoms`` (id -> arrow id), in ``world``,
    at the geom's centre: ``ContactForces(geoms, contacts, centres)``, ``centres`` in the
    order of ``geoms``, ``contacts`` ((geom1, geom2), MuJoCo's force along the contact
    frame's normal and tangents, the frame's rows) for each contact on one of them. A geom
    without contact gets a zero force.

    Python floats, not a numpy product: the same bits on every machine (numpy's product
    goes to OpenBLAS, whose kernel, with or without fused multiply-adds, depends on the
    CPU)."""

    @staticmethod
    def _make(geoms: dict[int, str], contacts: list[tuple], centres: list[list[float]]
              ) -> list[Arrow]:
        total = {g: [0.0, 0.0, 0.0] for g in geoms}
        for pair, (n, t1, t2), a in contacts:
            # the frame's rows are its axes in world; the force acts on geom2
            f = (a[0] * n + a[3] * t1 + a[6] * t2, a[1] * n + a[4] * t1 + a[7] * t2,
                 a[2] * n + a[5] * t1 + a[8] * t2)
            for g, sign in zip(pair, (-1.0, 1.0)):
                acc = total.get(g)
                if acc is not None:
                    acc[0] += sign * f[0]
                    acc[1] += sign * f[1]
                    acc[2] += sign * f[2]
        return [Arrow(name, f32_tuple(xyz), f32_tuple(total[g]))
                for (g, name), xyz in zip(geoms.items(), centres)]
