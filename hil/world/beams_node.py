"""Seed 000's beams world as a node on the run's CAN bus, stepped by the lockstep simulator.

Every ``DT_US`` the node applies the last ``actuator_command`` it heard (saturated by the
world), steps Eq. 1-3, and publishes ``body_pose`` and ``body_rate`` every control period
and the force sensor's ``force`` (Eq. 6) at 100 Hz. It also meters the ground truth the
experiments report: the Eq. 11 energy of the applied actuation and the peak angles.
"""
from __future__ import annotations

import math

from hexhil.hil.canbus.bus import CanBus, Endpoint, message
from hexhil.hil.run_result import BeamsOutcome
from hexhil.hil.scenario.beams import MAX_TIME_S
from hexhil.hil.world import scene
from hexhil.hil.world.beams import DT_US, SENSOR_PERIOD_US, BeamsWorld
from hexhil.protocol import can_frames

CONTROL_PERIOD_US = 2000      # Sec. II-I: control input every 0.002 s; pose and rate as often
NO_CONTACT_LIMIT_US = 5_000_000  # a push that has not reached the beams in 5 s never will


def energy_increment_j(u: tuple[float, float, float], qd: tuple[float, float, float],
                       dt_s: float = CONTROL_PERIOD_US * 1e-6) -> float:
    """One term of Eq. 11: positive actuator power only (actuators do not store energy)."""
    return sum(max(ui * vi, 0.0) for ui, vi in zip(u, qd)) * dt_s


class BeamsNode:
    """The world, its sensors and its actuators on the CAN bus."""

    period_us = DT_US

    def __init__(self, world: BeamsWorld, max_time_s: float = MAX_TIME_S) -> None:
        self.world = world
        self.max_time_us = max_time_s * 1e6
        self.energy_j = 0.0
        self.peak_rad = [0.0, 0.0]
        self.sample_no = 0
        self.port: Endpoint | None = None
        self.faults: Any = None   # the run's (hil/servobus/faults.py): force_bias, force_dropout

    def attach(self, can: CanBus) -> None:
        self.port = can.endpoint("tx")

    @property
    def t_us(self) -> int:
        return self.world.t_us

    def step(self) -> None:
        world, port = self.world, self.port
        for msg in port.frames():
            name, sig = can_frames.decode(msg.arbitration_id, bytes(msg.data))
            if name == "actuator_command":
                world.command(sig["fx_n"], sig["tau1_nm"], sig["tau2_nm"])
        world.step()
        t, s = world.t_us, world.state
        self.peak_rad = [max(self.peak_rad[0], abs(s.roll_rad)),
                         max(self.peak_rad[1], abs(s.pitch_rad))]
        if t % CONTROL_PERIOD_US == 0:
            port.send(message("body_pose", x_m=s.x_m, roll_rad=s.roll_rad,
                              pitch_rad=s.pitch_rad))
            port.send(message("body_rate", vx_m_s=s.vx_m_s,
                              roll_rate_rad_s=s.roll_rate_rad_s,
                              pitch_rate_rad_s=s.pitch_rate_rad_s))
            if not world.free_run:
                self.energy_j += energy_increment_j(world.applied, s.qd())
        if t % SENSOR_PERIOD_US == 0:
            f = world.sense_force()
            if self.faults is not None:
                f = self.faults.force_sample(f)
            if f is not None:
                port.send(message("force", fx_n=f[0], fy_n=f[1], fz_n=f[2],
                                  sample=self.sample_no))
            self.sample_no += 1

    def scene_shapes(self) -> list[scene.Shape]:
        return scene.beams_shapes(self.world.geometry, self.world.beams)

    def scene_frames(self) -> list[scene.Frame]:
        return scene.beams_frames(self.world)

    def scene_arrows(self) -> list[scene.Arrow]:
        return scene.beams_arrows(self.world)

    def done(self) -> bool:
        w = self.world
        if w.flipped or w.passed():
            return True
        if w.first_contact_us is None:
            return w.t_us > NO_CONTACT_LIMIT_US
        return w.t_us - w.first_contact_us > self.max_time_us

    def outcome(self) -> BeamsOutcome:
        w = self.world
        return BeamsOutcome(
            traversed=w.passed(), flipped=w.flipped, stuck=not w.passed() and not w.flipped,
            energy_J=self.energy_j, k0=w.geometry.k0_nm_per_rad(),
            t_contact_s=None if w.first_contact_us is None else w.first_contact_us * 1e-6,
            t_end_s=w.t_us * 1e-6, x_end_m=w.state.x_m,
            max_roll_deg=math.degrees(self.peak_rad[0]),
            max_pitch_deg=math.degrees(self.peak_rad[1]))

