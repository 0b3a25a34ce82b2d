"""The real robot's error sources, selected by ``[world] model = "real"``.

``ideal`` (the default for scenario files, so regression runs and conformance digests do not
move) is the world as it landed: identical servos, smooth fixed obstacles, a deterministic
run. ``real`` (the default of ``hexhil experiment tactile-hexapod``) adds what a built
seed-003 robot has; every figure's source is in docs/hexapod-world.md ("Real model"):

- servos: supply 11 V (paper Sec. 3.1: 10-12 V; e-manual figures are at 12 V, torque scales
  with voltage), gear backlash between motor and output (the potentiometer sits on the
  output), the potentiometer's 0.29 deg resolution and read noise, and per-unit offsets and
  stall torques drawn from ``world.units_seed`` (default: the scenario seed);
- contacts: tibia and switch plate meet obstacles with polypropylene's friction (their own
  0.3, not the obstacle's) and the plate's face is rounded, so a leg caught on an
  obstacle's side can slide off it (paper Sec. 2.3);
- obstacles: fixed to the ground by default, as the paper's held: its legs "get stuck behind
  the obstacles and the robot pushes itself backward", unable to reach a goal 1 m away (Sec.
  4); ``world.obstacle_body = "free"`` makes them loose bodies with mass and floor friction
  that can slide, tip or be stepped on (our wooden ones are shoved aside, see docs);
- trial noise from the run seed: each foot's friction, so repeated trials differ.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
import numpy as np

from hexhil.hil.scenario.world_section import WorldConfig
from hexhil.hil.world import actuator as act

RATED_SUPPLY_V = 12.0          # e-manual: stall torque and no-load speed are given at 12 V
SUPPLY_V = 11.0                # paper Sec. 3.1: servo supply 10-12 V; the middle of it
BACKLASH_RAD = 0.01            # Webots' Dynamixel backlash; MX-28 datasheet 0.33 deg (docs)
OFFSET_SD_UNITS = 1.0          # per-unit zero offset in position units: AX-12 positions are
                               # "within about half a degree" (Tira-Thompson 2008), = 2 sd
STALL_SPREAD_SD = 0.05         # per-unit stall torque, relative: motor data "+/- 10 %"
                               # (Beckhoff AM8100 docs; no AX-12 figure), taken as 2 sd
READ_NOISE_SD_UNITS = 0.5      # potentiometer read error: the ATmega8 ADC's 0.5 LSB
                               # differential non-linearity (datasheet 2486, Table 103; no
                               # AX-12 figure), one LSB a position unit, drawn per reading
FOOT_FRICTION_SD = 0.10        # per-foot, per-trial friction, relative: ASTM C1028's
                               # reproducibility sd, about 0.05 at mu 0.55 (docs)
OBSTACLE_DENSITY_KG_M3 = 600.0  # wood, Engineering ToolBox: pine 350-670, oak 600-900 (the
                                # paper does not name the material: our choice of wood)
OBSTACLE_FLOOR_FRICTION = 0.4   # wood on wood 0.12-0.65 static, grain and finish (docs)
LEG_FRICTION = 0.3              # polypropylene plate and tibia (paper Sec. 2.3)


@dataclass
class RealModel:
    """One robot (unit spread, from the units seed) in one trial (noise, from the run seed)."""

    offsets_rad: np.ndarray      # what each potentiometer reads minus the true angle
    stall_nm: np.ndarray         # each unit's stall torque at the supply voltage
    foot_friction: np.ndarray    # each foot's friction in this trial
    noise_seed: int
    free_obstacles: bool
    motor: act.Motor = act.AX12


def from_scenario(world: WorldConfig, motor: act.Motor, seed: int, foot_friction: float,
                  n_joints: int, n_feet: int) -> RealModel | None:
    """The real model a scenario's ``[world]`` asks for, or None for the ideal world."""
    if world.ideal:
        return None
    units = np.random.default_rng([seed if world.units_seed is None else world.units_seed, 3])
    trial = np.random.default_rng([seed, 21])
    offsets = units.normal(0.0, OFFSET_SD_UNITS, n_joints) * act.POSITION_UNIT_RAD
    stall = motor.stall_torque_nm * SUPPLY_V / motor.rated_supply_v * (
        1.0 + np.clip(units.normal(0.0, STALL_SPREAD_SD, n_joints), -2 * STALL_SPREAD_SD,
                      2 * STALL_SPREAD_SD))
    feet = foot_friction * np.clip(1.0 + trial.normal(0.0, FOOT_FRICTION_SD, n_feet), 0.5, 1.5)
    return RealModel(offsets, stall, feet, int(trial.integers(2**31)),
                     world.obstacle_body == "free", motor)


class RealDriveBank(act.DriveBank):
    """The ideal drive bank plus backlash, potentiometer resolution and noise, unit offsets
    and stall torques.

    Backlash: the motor side sits ``gap`` ahead of the output within +-BACKLASH_RAD / 2.
    Torque passes only while the motor presses on the side it pushes toward; after a
    reversal (or with the duty at 0) the motor crosses the gap at its free speed at that
    duty, ``u * omega_noload``, relative to the moving output, and nothing passes meanwhile.
    Back-EMF damping stays on the joint (MuJoCo damping), a simplification."""

    def __init__(self, q0_rad: np.ndarray, real: RealModel,
                 joints: tuple[np.ndarray, np.ndarray]) -> None:
        super().__init__(q0_rad, real.motor, joints)
        self.real = real
        self.read_offset_rad[:] = real.offsets_rad
        self._qd = joints[1]
        self._gap = np.zeros(len(q0_rad))
        self._half = BACKLASH_RAD / 2
        self._rng = np.random.default_rng(real.noise_seed)
        self._omega = real.stall_nm / real.motor.back_emf_damping_nm_s   # no-load speed per unit

    def control_into(self, q_rad: np.ndarray, dt_s: float, ctrl: np.ndarray) -> None:
        ctrl[:] = self.control(q_rad, dt_s)

    def control(self, q_rad: np.ndarray, dt_s: float) -> np.ndarray:
        unit = act.POSITION_UNIT_RAD
        seen = q_rad + self.real.offsets_rad + self._rng.normal(0.0, READ_NOISE_SD_UNITS * unit,
                                                                len(q_rad))
        seen = np.round(seen / unit) * unit         # 0.29 deg resolution (e-manual)
        u = self.duty_for(seen, dt_s)
        gap, half = self._gap, self._half
        engaged = ((gap >= half) & (u > 0)) | ((gap <= -half) & (u < 0))
        moved = gap + (u * self._omega - self._qd) * dt_s
        np.clip(moved, -half, half, out=moved)
        self._gap = np.where(engaged, gap, moved)
        return np.where(engaged, self.real.stall_nm * u, 0.0)


def obstacle_mass_kg(length_m: float, width_m: float, height_m: float) -> float:
    """A half-ellipsoid's mass at OBSTACLE_DENSITY_KG_M3."""
    return OBSTACLE_DENSITY_KG_M3 * 2.0 / 3.0 * math.pi * length_m / 2 * width_m / 2 * height_m
