"""What a world looks like, as plain values the recorder turns into Foxglove's 3D scene.

A world that can be seen offers ``scene_shapes()`` (the geometry, each shape fixed in one
moving frame; re-sent only when it changes, e.g. a switch plate's colour), ``scene_frames()``
(every moving frame's pose, each ground-truth sample) and ``scene_arrows()``
(forces, each sample). The hexapod's shapes are read from its compiled MuJoCo model, so
the scene has the sizes the physics has; seed 000's body and beams from their geometry.
The values are in hil/world/scene_values.py. No host_tools here: the simulator hands them
to the recorder as they are.
"""
from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from hexhil.hil.world.beams import BeamsWorld
from hexhil.hil.world.scene_values import (Arrow, ContactForces, Frame, JointFrames, Shape,
                                     f32_tuple)

ROBOT_RGBA = (0.25, 0.45, 0.75, 1.0)
FOOT_RGBA = (0.15, 0.15, 0.15, 1.0)
PLATE_OPEN_RGBA = (0.8, 0.8, 0.8, 1.0)
PLATE_PRESSED_RGBA = (0.95, 0.15, 0.1, 1.0)
OBSTACLE_RGBA = (0.6, 0.45, 0.3, 1.0)
BEAM_RGBA = (0.55, 0.55, 0.5, 0.9)
BEAM_THICKNESS_M = 0.004  # drawn only: seed 000's beams are massless plates (Sec. II-A)
IDENTITY = (1.0, 0.0, 0.0, 0.0)


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
        out.append(Shape(name, frame, kind, f32_tuple(model.geom_pos[g]),
                         f32_tuple(model.geom_quat[g]), f32_tuple(extents), rgba))
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
        bodies = []
        for b in range(1, model.nbody):
            parent = int(model.body_parentid[b])
            j = int(model.body_jntadr[b])
            bodies.append((body(b), body(parent) if parent else "world",
                           int(model.jnt_qposadr[j]), parent == 0,
                           f32_tuple(model.body_pos[b]), tuple(model.body_quat[b].tolist()),
                           tuple(model.jnt_axis[j].tolist())))
        self._bodies = tuple(bodies)   # one object: a window's pickle holds it once

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

    def frames(self, data: Any) -> JointFrames:
        """Every body's pose, as the joint coordinates it follows from (``JointFrames``)."""
        return JointFrames(self._bodies, data.qpos.tolist())

    def arrows(self, data: Any) -> ContactForces:
        return contact_forces(self.model, data, self._forces)


def contact_forces(model: Any, data: Any, geoms: dict[int, str]) -> ContactForces:
    """The contacts on the geoms in ``geoms`` (id -> arrow id), as ``ContactForces``:
    MuJoCo's force in each contact's frame, the frame, and the geoms' centres, read now;
    the sums are made where the recorder encodes them."""
    f6 = np.zeros(6)
    contacts = data.contact   # its columns: a contact object each costs more
    frames = contacts.frame.tolist()
    held = []
    for i, pair in enumerate(zip(contacts.geom1.tolist(), contacts.geom2.tolist())):
        if pair[0] in geoms or pair[1] in geoms:
            mujoco.mj_contactForce(model, data, i, f6)
            held.append((pair, f6[:3].tolist(), frames[i]))
    return ContactForces(geoms, held, data.geom_xpos[list(geoms)].tolist())


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
    body = Frame("body", "world", f32_tuple((s.x_m, 0.0, g.height_m)),
                 f32_tuple((cp * cr, cp * sr, sp * cr, -sp * sr)))
    out = [body]
    for i, bp in enumerate(world.beams):
        lo, hi = g.beam_y_range(i)
        out.append(Frame(f"beam{i}", "world", f32_tuple((0.0, (lo + hi) / 2, bp.hb_m)),
                         f32_tuple(_quat_y(world.last.theta_rad[i]))))
    return out


def beams_arrows(world: BeamsWorld) -> list[Arrow]:
    """The beams' summed contact force (Eq. 5: F1 + F2, what the force sensor reads before
    noise), drawn at the body's nose."""
    g, s = world.geometry, world.state
    return [Arrow("contact", f32_tuple((s.x_m + g.a_m, 0.0, g.height_m)),
                  f32_tuple(world.last.contact_n))]
