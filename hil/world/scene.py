"""What a world looks like, as plain values the recorder turns into Foxglove's 3D scene.

A world that can be seen offers ``scene_shapes()`` (the geometry, each shape fixed in one
moving frame; re-sent only when it changes, e.g. a switch plate's colour), ``scene_frames()``
(every moving frame's pose, each ground-truth sample) and ``scene_arrows()``
(forces, each sample). The hexapod's shapes are read from its compiled MuJoCo model, so
the scene has the sizes the physics has; seed 000's body and beams from their geometry.
No host_tools here: the simulator hands these values to the recorder as they are.
"""
from __future__ import annotations

import math
import struct
from typing import Any, NamedTuple

import mujoco
import numpy as np

from hil.world.beams import BeamsWorld

ROBOT_RGBA = (0.25, 0.45, 0.75, 1.0)
FOOT_RGBA = (0.15, 0.15, 0.15, 1.0)
PLATE_OPEN_RGBA = (0.8, 0.8, 0.8, 1.0)
PLATE_PRESSED_RGBA = (0.95, 0.15, 0.1, 1.0)
OBSTACLE_RGBA = (0.6, 0.45, 0.3, 1.0)
BEAM_RGBA = (0.55, 0.55, 0.5, 0.9)
BEAM_THICKNESS_M = 0.004  # drawn only: seed 000's beams are massless plates (Sec. II-A)
IDENTITY = (1.0, 0.0, 0.0, 0.0)
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


def _t(v: Any) -> tuple[float, ...]:
    """Floats rounded to float32: the scene is for looking at (0.1 um at 1 m), and the
    zeroed low bits let zstd pack the 10 Hz poses and forces to about half."""
    fmt = _F32[len(v)]
    return fmt.unpack(fmt.pack(*v))   # numpy's floats and ints pack as their float()


def model_shapes(model: Any, pressed: dict[str, bool]) -> list[Shape]:
    """Every geom of a MuJoCo model but the ground plane, in its body's frame (``world``
    for static geoms), with the model's sizes. ``pressed``: geom name -> switch level,
    for the plates that change colour."""
    out = []
    for g in range(model.ngeom):
        gtype = int(model.geom_type[g])
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        body = int(model.geom_bodyid[g])
        frame = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) if body else "world"
        size = model.geom_size[g]
        if gtype == mujoco.mjtGeom.mjGEOM_BOX:
            kind, extents = "cube", 2 * size
        elif gtype == mujoco.mjtGeom.mjGEOM_CAPSULE:  # drawn as its cylinder, caps included
            kind, extents = "cylinder", (2 * size[0], 2 * size[0], 2 * (size[1] + size[0]))
        elif gtype == mujoco.mjtGeom.mjGEOM_SPHERE:
            kind, extents = "sphere", (2 * size[0],) * 3
        elif gtype == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
            kind, extents = "sphere", 2 * size
        else:
            continue
        if name in pressed:
            rgba = PLATE_PRESSED_RGBA if pressed[name] else PLATE_OPEN_RGBA
        elif body == 0:
            rgba = OBSTACLE_RGBA
        elif kind == "sphere" and body:
            rgba = FOOT_RGBA
        else:
            rgba = ROBOT_RGBA
        out.append(Shape(name, frame, kind, _t(model.geom_pos[g]), _t(model.geom_quat[g]),
                         _t(extents), rgba))
    return out


class ModelScene:
    """A MuJoCo world's scene, its constant parts looked up once (shapes, names, parents,
    offsets, axes, geom ids): it is asked for at every ground-truth sample.

    ``plates``: the geoms whose colour shows a switch level; ``forces``: the geoms whose
    contact force is drawn (geom name -> arrow id)."""

    def __init__(self, model: Any, plates: list[str], forces: list[str]) -> None:
        def body(b: int) -> str:
            return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)

        self.model = model
        self._shapes = model_shapes(model, {p: False for p in plates})
        index = {sh.id: i for i, sh in enumerate(self._shapes)}
        self._plates = [index[p] for p in plates]
        self._levels: tuple | None = None   # the last shapes() call's levels, and its answer
        self._coloured: list[Shape] = []
        self._forces = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, g): g for g in forces}
        self._bodies = []
        for b in range(1, model.nbody):
            parent = int(model.body_parentid[b])
            j = int(model.body_jntadr[b])
            self._bodies.append((body(b), body(parent) if parent else "world",
                                 int(model.jnt_qposadr[j]), parent == 0,
                                 _t(model.body_pos[b]), tuple(model.body_quat[b].tolist()),
                                 tuple(model.jnt_axis[j].tolist())))

    def shapes(self, levels: list[bool]) -> list[Shape]:
        """Every shape, the plates coloured by ``levels`` (True = pressed): the same list
        while the levels stay, so a caller sees at once that nothing changed."""
        key = tuple(levels)
        if key != self._levels:
            out = list(self._shapes)
            for i, pressed in zip(self._plates, levels):
                if pressed:
                    out[i] = out[i]._replace(rgba=PLATE_PRESSED_RGBA)
            self._levels, self._coloured = key, out
        return self._coloured

    def frames(self, data: Any) -> list[Frame]:
        """Every body's pose from the joint coordinates (as ``/body`` and ``/joints`` have
        them): a free body's in ``world``, a body on one hinge in its parent's (the model's
        fixed offset turned by the joint angle). Relative poses keep the constant parts
        exact zeros or constants, which protobuf leaves out or zstd packs."""
        out = []
        qpos = data.qpos.tolist()
        for name, parent, adr, free, pos, (w1, x1, y1, z1), (ax, ay, az) in self._bodies:
            if free:  # a free joint: position, then the quaternion
                out.append(Frame(name, parent, _t(qpos[adr:adr + 3]), _t(qpos[adr + 3:adr + 7])))
                continue
            half = qpos[adr] / 2
            s = math.sin(half)
            w2, x2, y2, z2 = math.cos(half), s * ax, s * ay, s * az
            quat = (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2 + 0.0,   # no -0.0
                    w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2 + 0.0,
                    w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2 + 0.0,
                    w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2 + 0.0)
            out.append(Frame(name, parent, pos, _t(quat)))
        return out

    def arrows(self, data: Any) -> list[Arrow]:
        return contact_forces(self.model, data, self._forces)


def contact_forces(model: Any, data: Any, geoms: dict[int, str]) -> list[Arrow]:
    """The summed contact force on each geom in ``geoms`` (id -> arrow id), in ``world``,
    at the geom's centre; geoms without contact get a zero force.

    Python floats, not a numpy product: the same bits on every machine (numpy's product
    goes to OpenBLAS, whose kernel, with or without fused multiply-adds, depends on the
    CPU), and a third of the time for the handful of contacts a sample has."""
    total = {g: [0.0, 0.0, 0.0] for g in geoms}
    f6 = np.zeros(6)
    contacts = data.contact   # its columns: a contact object each costs more
    frames = contacts.frame
    for i, pair in enumerate(zip(contacts.geom1.tolist(), contacts.geom2.tolist())):
        if pair[0] not in total and pair[1] not in total:
            continue
        mujoco.mj_contactForce(model, data, i, f6)
        n, t1, t2 = f6[:3].tolist()   # along the contact frame's normal and tangents
        # the frame's rows are its axes in world; the force acts on geom2
        a = frames[i].tolist()
        f = (a[0] * n + a[3] * t1 + a[6] * t2, a[1] * n + a[4] * t1 + a[7] * t2,
             a[2] * n + a[5] * t1 + a[8] * t2)
        for g, sign in zip(pair, (-1.0, 1.0)):
            acc = total.get(g)
            if acc is not None:
                acc[0] += sign * f[0]
                acc[1] += sign * f[1]
                acc[2] += sign * f[2]
    xpos = data.geom_xpos
    return [Arrow(name, _t(xpos[g].tolist()), _t(total[g])) for g, name in geoms.items()]


def _quat_y(angle_rad: float) -> tuple[float, float, float, float]:
    return (math.cos(angle_rad / 2), 0.0, math.sin(angle_rad / 2), 0.0)


def beams_shapes(geometry: Any, beams: list[Any]) -> list[Shape]:
    """Seed 000's ellipsoid body (2a x 2b x 2c, Sec. II-A) and its beam plates (w x L,
    hinged at their bottom edge, frames ``beam0``/``beam1``)."""
    g = geometry
    out = [Shape("body", "body", "sphere", (0.0, 0.0, 0.0), IDENTITY,
                 (2 * g.a_m, 2 * g.b_m, 2 * g.c_m), ROBOT_RGBA)]
    for i in range(len(beams)):
        out.append(Shape(f"beam{i}", f"beam{i}", "cube", (0.0, 0.0, g.beam_length_m / 2),
                         IDENTITY, (BEAM_THICKNESS_M, g.beam_width_m, g.beam_length_m),
                         BEAM_RGBA))
    return out


def beams_frames(world: BeamsWorld) -> list[Frame]:
    """The body (centre at height H; R = Ry(pitch) Rx(roll)) and each beam's hinge frame,
    turned forward by its deflection theta about +y."""
    g, s = world.geometry, world.state
    cr, sr = math.cos(s.roll_rad / 2), math.sin(s.roll_rad / 2)
    cp, sp = math.cos(s.pitch_rad / 2), math.sin(s.pitch_rad / 2)
    body = Frame("body", "world", _t((s.x_m, 0.0, g.height_m)),
                 _t((cp * cr, cp * sr, sp * cr, -sp * sr)))
    out = [body]
    for i, bp in enumerate(world.beams):
        lo, hi = g.beam_y_range(i)
        out.append(Frame(f"beam{i}", "world", _t((0.0, (lo + hi) / 2, bp.hb_m)),
                         _t(_quat_y(world.last.theta_rad[i]))))
    return out


def beams_arrows(world: BeamsWorld) -> list[Arrow]:
    """The beams' summed contact force (Eq. 5: F1 + F2, what the force sensor reads before
    noise), drawn at the body's nose."""
    g, s = world.geometry, world.state
    return [Arrow("contact", _t((s.x_m + g.a_m, 0.0, g.height_m)), _t(world.last.contact_n))]
