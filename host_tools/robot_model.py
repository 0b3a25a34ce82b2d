"""The hexapod as a URDF, for tools that read robot descriptions (RViz, Foxglove's URDF
layer, robotics libraries), generated from the same parameters as the MuJoCo world.

One source: ``protocol/hexapod.py`` (mounts, link lengths, body box, servo directions) and
the world's ``RobotParams`` (link radii, masses, switch plates), through the same
``hil.world.hexapod_world`` that builds the MJCF. The joints have the MJCF's zero pose and axes,
so a URDF joint angle is the servo angle (0 at the AX-12's centre): the coxa along the
mounting yaw, the femur horizontal, the tibia hanging straight down. Each leg ends in a
fixed ``<leg>_foot`` link at the foot sphere's centre.
"""
from __future__ import annotations

import math
from xml.sax.saxutils import quoteattr

from hexhil.hil.world import actuator as act
from hexhil.hil.world.hexapod_world import RobotParams
from hexhil.protocol import hexapod as robot_desc
from hexhil.protocol.hexapod import LEGS

SERVO_RANGE_RAD = math.radians(150)  # the AX-12's 300 deg travel, as the MJCF's joint range
LINK_RADIUS_M = 0.012                 # the coxa and femur capsules of the MJCF
GREY, BLUE = "0.8 0.8 0.8 1", "0.25 0.45 0.75 1"


def _f(*v: float) -> str:
    return " ".join(f"{x:.6g}" for x in v)


def _inertial(mass_kg: float, xyz: tuple[float, float, float], ixx: float, iyy: float,
              izz: float) -> str:
    return (f'<inertial><origin xyz="{_f(*xyz)}"/><mass value="{mass_kg:.6g}"/>'
            f'<inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/>'
            f'</inertial>')


def _rod(length_m: float, radius_m: float, along_x: bool) -> str:
    """Visual and collision cylinder of a link: along +x (coxa, femur) or -z (tibia)."""
    origin = (f'<origin xyz="{_f(length_m / 2, 0, 0)}" rpy="0 {math.pi / 2:.6g} 0"/>' if along_x
              else f'<origin xyz="{_f(0, 0, -length_m / 2)}"/>')
    geom = f'<geometry><cylinder radius="{radius_m:.6g}" length="{length_m:.6g}"/></geometry>'
    return (f'<visual>{origin}{geom}<material name="blue"/></visual>'
            f'<collision>{origin}{geom}</collision>')


def _link(name: str, length_m: float, radius_m: float, mass_kg: float, along_x: bool) -> str:
    """A rod link with the inertia of a thin rod of its mass about its centre."""
    i_cross = mass_kg * length_m ** 2 / 12
    i_axis = mass_kg * radius_m ** 2 / 2
    if along_x:
        inertial = _inertial(mass_kg, (length_m / 2, 0, 0), i_axis, i_cross, i_cross)
    else:
        inertial = _inertial(mass_kg, (0, 0, -length_m / 2), i_cross, i_cross, i_axis)
    return f'  <link name="{name}">{inertial}{_rod(length_m, radius_m, along_x)}</link>\n'


def _joint(name: str, parent: str, xyz: tuple[float, float, float], yaw_rad: float,
           axis: tuple[float, float, float]) -> str:
    return (f'  <joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{name}"/><origin xyz="{_f(*xyz)}" rpy="0 0 {yaw_rad:.12g}"/>'
            f'<axis xyz="{_f(*axis)}"/><limit lower="{-SERVO_RANGE_RAD:.6g}" '
            f'upper="{SERVO_RANGE_RAD:.6g}" effort="{act.AX12.stall_torque_nm:.6g}" '
            f'velocity="{act.AX12.no_load_speed_rad_s:.6g}"/></joint>\n')


def urdf(params: RobotParams | None = None) -> str:
    """The URDF document of the hexapod (joint names as in the MJCF: ``LF_coxa`` ...)."""
    p = params or RobotParams()
    bx, by, bz = p.body_half_m
    box = f'<geometry><box size="{_f(2 * bx, 2 * by, 2 * bz)}"/></geometry>'
    m = p.body_kg
    body_inertial = _inertial(m, (0, 0, 0), m * (by * by + bz * bz) / 3,
                              m * (bx * bx + bz * bz) / 3, m * (bx * bx + by * by) / 3)
    parts = [f'<?xml version="1.0"?>\n<robot name={quoteattr("hexhil-hexapod")}>\n',
             f'  <material name="blue"><color rgba="{BLUE}"/></material>\n',
             f'  <material name="grey"><color rgba="{GREY}"/></material>\n',
             f'  <link name="body">{body_inertial}'
             f'<visual>{box}<material name="grey"/></visual><collision>{box}</collision></link>\n']
    for name, (mx, my, yaw), dirs in zip(LEGS, p.mounts, robot_desc.DIRECTIONS):
        parts.append(_joint(f"{name}_coxa", "body", (mx, my, 0.0), yaw, (0, 0, 1)))
        parts.append(_link(f"{name}_coxa", p.coxa_m, LINK_RADIUS_M, p.coxa_kg, True))
        parts.append(_joint(f"{name}_femur", f"{name}_coxa", (p.coxa_m, 0, 0), 0.0,
                            (0, -dirs[1], 0)))
        parts.append(_link(f"{name}_femur", p.femur_m, LINK_RADIUS_M, p.femur_kg, True))
        parts.append(_joint(f"{name}_tibia", f"{name}_femur", (p.femur_m, 0, 0), 0.0,
                            (0, -dirs[2], 0)))
        parts.append(_link(f"{name}_tibia", p.tibia_m, p.tibia_radius_m, p.tibia_kg, False))
        sphere = f'<geometry><sphere radius="{p.foot_radius_m:.6g}"/></geometry>'
        parts.append(f'  <link name="{name}_foot"><visual>{sphere}<material name="grey"/>'
                     f'</visual><collision>{sphere}</collision></link>\n')
        parts.append(f'  <joint name="{name}_foot" type="fixed"><parent link="{name}_tibia"/>'
                     f'<child link="{name}_foot"/><origin xyz="{_f(0, 0, -p.tibia_m)}"/></joint>\n')
    parts.append("</robot>\n")
    return "".join(parts)
