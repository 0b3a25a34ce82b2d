"""The 3D scene's Foxglove messages, built from the plain shapes, frames and arrows a world
offers (hil/world/scene.py): ``foxglove.SceneUpdate`` for geometry and forces,
``foxglove.FrameTransforms`` for the moving frames (``protobuf.encode_frame_transforms``).

Geometry is frame-locked to the moving frame it belongs to, so it is sent once (and again
when it changes) while each sample only moves the frames: a 10 s walking run's scene adds
about 200 messages and about 35 kB after compression.
"""
from __future__ import annotations

import math
import struct
from typing import Any, Sequence

from foxglove_schemas_protobuf.ArrowPrimitive_pb2 import ArrowPrimitive
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

ARROW_M_PER_N = 0.02       # drawn length: the hexapod's 14.7 N weight is 0.29 m of arrows
ARROW_MIN_N = 0.05         # smaller forces are not drawn (the touch threshold of the feet)
ARROW_SHAFT_M = 0.004
ARROW_RGBA = (1.0, 0.8, 0.0, 1.0)
_PRIMITIVE_FIELD = {"cube": "cubes", "sphere": "spheres", "cylinder": "cylinders"}
_F32 = struct.Struct("<4f")


def _f32(*v: float) -> tuple[float, ...]:
    """Rounded to float32, as the world rounds the scene (hil/world/scene.py): zstd packs
    the zeroed low bits."""
    return _F32.unpack(_F32.pack(*v, *(0.0,) * (4 - len(v))))[:len(v)]


def _pose(msg: Pose, position_m: Sequence[float], quat_wxyz: Sequence[float]) -> None:
    msg.position.x, msg.position.y, msg.position.z = position_m
    msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z = quat_wxyz


def _colour(msg: Color, rgba: Sequence[float]) -> None:
    msg.r, msg.g, msg.b, msg.a = rgba


def encode_shapes(t_ns: int, shapes: Sequence[Any]) -> bytes:
    """One SceneUpdate with an entity per shape (``hil.world.scene.Shape``), frame-locked to
    its frame, replacing the entity of the same id sent before."""
    update = SceneUpdate()
    for s in shapes:
        e = update.entities.add(id=s.id, frame_id=s.frame, frame_locked=True)
        e.timestamp.FromNanoseconds(t_ns)
        prim = getattr(e, _PRIMITIVE_FIELD[s.kind]).add()
        _pose(prim.pose, s.position_m, s.quat_wxyz)
        prim.size.x, prim.size.y, prim.size.z = s.size_m
        _colour(prim.color, s.rgba)
    return update.SerializeToString()


def _direction_quat(fx: float, fy: float, fz: float, norm: float
                    ) -> tuple[float, float, float, float]:
    """The rotation (w, x, y, z) turning +x (Foxglove's arrow axis) onto the force."""
    dx, dy, dz = fx / norm, fy / norm, fz / norm
    w = 1.0 + dx
    if w < 1e-9:  # straight back: half a turn about z
        return (0.0, 0.0, 0.0, 1.0)
    x, y, z = 0.0, -dz, dy          # +x cross d
    n = math.sqrt(w * w + y * y + z * z)
    return (w / n, x, y / n, z / n)


def encode_arrows(t_ns: int, arrows: Sequence[Any]) -> bytes:
    """One SceneUpdate whose entity ``forces`` (in ``world``) holds an arrow per force above
    ``ARROW_MIN_N``, ``ARROW_M_PER_N`` long a newton (``hil.world.scene.Arrow``s, or the
    same fields as plain tuples)."""
    update = SceneUpdate()
    e = update.entities.add(id="forces", frame_id="world")
    e.timestamp.FromNanoseconds(t_ns)
    for _, origin_m, (fx, fy, fz) in arrows:
        norm = math.sqrt(fx * fx + fy * fy + fz * fz)
        if norm < ARROW_MIN_N:
            continue
        shaft, head = _f32(0.8 * norm * ARROW_M_PER_N, 0.2 * norm * ARROW_M_PER_N)
        prim = e.arrows.add(shaft_length=shaft, head_length=head,
                            shaft_diameter=ARROW_SHAFT_M, head_diameter=2.5 * ARROW_SHAFT_M)
        _pose(prim.pose, origin_m, _f32(*_direction_quat(fx, fy, fz, norm)))
        _colour(prim.color, ARROW_RGBA)
    return update.SerializeToString()

