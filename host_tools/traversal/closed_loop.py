"""The closed loop of Sec. III-C/D/E over a python-can bus, in lockstep virtual time.

Three nodes share one in-process ``virtual`` CAN channel, each through its own python-can Bus:

* the world (hil/world/beams.py): steps Eq. 1-3 every 0.2 ms; every 2 ms it publishes
  ``body_pose`` and ``body_rate``; every 10 ms the force sensor publishes ``force`` (Eq. 6);
  it applies the last ``actuator_command`` it received (saturated);
* the estimator/planner node: collects the force samples from first contact, estimates the
  beams after the sensing window, and at the end of the sensory delay plans from the pose it
  last heard and publishes ``beam_estimate`` (with the mode);
* the controller: pushes with F_x until it has a plan, then runs Eq. 9 every 2 ms and sends
  ``actuator_command``.

One loop steps the world and drains every bus in a fixed order: no threads, no wall clock,
so a seed gives the same run byte for byte.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from hil.world.beam_body import PAPER_BODY, BeamParams, BodyGeometry
from hil.world.beams import DT_US, SENSOR_PERIOD_US, BeamsWorld, BodyState
from host_tools.traversal import estimator, landscape, planner
from host_tools.traversal.control import CONTROL_PERIOD_US, FeedbackLinearisation, energy_increment_j
from protocol import can_frames

RIGID_K_NM_PER_RAD = 100.0     # the avoidance baseline's map: beams as obstacles to roll past
_channels = itertools.count()


@dataclass
class RunConfig:
    k1: float
    k2: float
    hb1_m: float = 0.0
    hb2_m: float = 0.0
    strategy: str = "interact"        # interact | avoid | none
    fx_n: float = 1.0
    noise: float = 0.2
    delay_ms: float = 300.0
    sensing_ms: float = 300.0
    unknowns: int = 3                 # Sec. III-C uses three unknowns at 20 % noise
    method: str = "fast"
    seed: int = 0
    max_time_s: float = 8.0           # after first contact
    grid: landscape.Grid = field(default_factory=landscape.paper_grid)
    preload_nm: float = 0.0
    beam_mass_kg: float = 0.0


class _Node:
    """One python-can endpoint on the shared virtual channel, recording what it sends."""

    def __init__(self, channel: str, recorder: Any, direction: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        self.recorder, self.direction = recorder, direction

    def send(self, t_us: int, name: str, **signals: float) -> None:
        arb_id, data = can_frames.encode(name, **signals)
        self.bus.send(can.Message(arbitration_id=arb_id, data=data, is_extended_id=False,
                                  timestamp=t_us * 1e-6))
        if self.recorder is not None:
            self.recorder.can(t_us, arb_id, data, direction=self.direction)

    def drain(self) -> list[tuple[str, dict]]:
        out = []
        while (msg := self.bus.recv(timeout=0)) is not None:
            out.append(can_frames.decode(msg.arbitration_id, bytes(msg.data)))
        return out

    def close(self) -> None:
        self.bus.shutdown()


def run(cfg: RunConfig, recorder: Any = None, geometry: BodyGeometry = PAPER_BODY) -> dict:
    """One traversal; returns the outcome, the estimate, the plan and the Eq. 11 energy."""
    if cfg.strategy not in ("interact", "avoid", "none"):
        raise ValueError(f"unknown strategy {cfg.strategy!r}")
    truth = [BeamParams(cfg.k1, cfg.hb1_m, cfg.preload_nm, cfg.beam_mass_kg),
             BeamParams(cfg.k2, cfg.hb2_m, cfg.preload_nm, cfg.beam_mass_kg)]
    world = BeamsWorld(truth, geometry, BodyState(), noise=cfg.noise, seed=cfg.seed)
    channel = f"hexhil-beams-{next(_channels)}"
    w_node, e_node, c_node = (_Node(channel, recorder, d) for d in ("tx", "tx", "rx"))
    samples: list[tuple[int, tuple[float, float, float], tuple[float, float, float]]] = []
    est_pose = ctl_pose = (world.state.x_m, 0.0, 0.0)
    ctl_rate = (world.state.vx_m_s, 0.0, 0.0)
    contact_us: int | None = None
    est: estimator.Estimate | None = None
    the_plan: planner.Plan | None = None
    controller: FeedbackLinearisation | None = None
    start_pose = None
    energy = 0.0
    sample_no = 0
    delay_us = int(round(cfg.delay_ms * 1000))
    window_us = min(int(round(cfg.sensing_ms * 1000)), delay_us)
    peak = [0.0, 0.0]
    try:
        while True:
            world.step()
            t = world.t_us
            s = world.state
            peak = [max(peak[0], abs(s.roll_rad)), max(peak[1], abs(s.pitch_rad))]
            if t % CONTROL_PERIOD_US == 0:
                w_node.send(t, "body_pose", x_m=s.x_m, roll_rad=s.roll_rad, pitch_rad=s.pitch_rad)
                w_node.send(t, "body_rate", vx_m_s=s.vx_m_s, roll_rate_rad_s=s.roll_rate_rad_s,
                            pitch_rate_rad_s=s.pitch_rate_rad_s)
            if t % SENSOR_PERIOD_US == 0:
                fx, fy, fz = world.sense_force()
                w_node.send(t, "force", fx_n=fx, fy_n=fy, fz_n=fz, sample=sample_no)
                sample_no += 1
            # --- estimator / planner node
            for name, sig in e_node.drain():
                if name == "body_pose":
                    est_pose = (sig["x_m"], sig["roll_rad"], sig["pitch_rad"])
                elif name == "force":
                    f = (sig["fx_n"], sig["fy_n"], sig["fz_n"])
                    if contact_us is None and any(f):
                        contact_us = t
                    if contact_us is not None and t - contact_us < window_us:
                        samples.append((t, est_pose, f))
            if contact_us is not None and cfg.strategy == "interact" and est is None \
                    and t - contact_us >= window_us:
                est = estimator.estimate(np.array([p for _, p, _ in samples]),
                                         np.array([f for _, _, f in samples]), cfg.unknowns, cfg.method,
                                         geometry)
            plan_now = contact_us is not None and the_plan is None and (
                (cfg.strategy == "interact" and t - contact_us >= delay_us) or cfg.strategy == "avoid")
            if plan_now:
                start_pose = est_pose
                if cfg.strategy == "interact":
                    hb = 0.5 * (est.hb1_m + est.hb2_m) if cfg.unknowns == 3 else est.hb1_m
                    land = landscape.build(cfg.grid, est.hb1_m, est.hb2_m, geometry)
                    the_plan = planner.plan(land, est.k1, est.k2, start_pose)
                    model = [BeamParams(est.k1, est.hb1_m), BeamParams(est.k2, est.hb2_m)]
                    e_node.send(t, "beam_estimate", k1_nm_per_rad=est.k1, k2_nm_per_rad=est.k2, hb_m=hb,
                                mode=can_frames.MODE_NAMES.index(the_plan.mode))
                else:
                    land = landscape.build(cfg.grid, 0.0, 0.0, geometry)
                    the_plan = planner.plan(land, RIGID_K_NM_PER_RAD, RIGID_K_NM_PER_RAD, start_pose)
                    model = []                  # a geometric map knows no beam forces
                controller = FeedbackLinearisation(the_plan, t, model, geometry)
            # --- controller node
            if t % CONTROL_PERIOD_US == 0:
                for name, sig in c_node.drain():
                    if name == "body_pose":
                        ctl_pose = (sig["x_m"], sig["roll_rad"], sig["pitch_rad"])
                    elif name == "body_rate":
                        ctl_rate = (sig["vx_m_s"], sig["roll_rate_rad_s"], sig["pitch_rate_rad_s"])
                if controller is not None:
                    u = controller(t, ctl_pose, ctl_rate)
                else:
                    u = (cfg.fx_n, 0.0, 0.0)
                c_node.send(t, "actuator_command", fx_n=u[0], tau1_nm=u[1], tau2_nm=u[2])
                if not world.free_run:
                    energy += energy_increment_j(world.applied, s.qd())
            for name, sig in w_node.drain():
                if name == "actuator_command":
                    world.command(sig["fx_n"], sig["tau1_nm"], sig["tau2_nm"])
            if recorder is not None and t % 100_000 == 0:
                recorder.advance(t)
            if world.flipped or world.passed():
                break
            if world.first_contact_us is not None and t - world.first_contact_us > cfg.max_time_s * 1e6:
                break
            if world.first_contact_us is None and t > 5_000_000:
                break
    finally:
        for node in (w_node, e_node, c_node):
            node.close()
    out = {
        "strategy": cfg.strategy, "k1": cfg.k1, "k2": cfg.k2, "hb1_mm": cfg.hb1_m * 1e3,
        "hb2_mm": cfg.hb2_m * 1e3, "fx_n": cfg.fx_n, "noise": cfg.noise, "delay_ms": cfg.delay_ms,
        "seed": cfg.seed, "traversed": world.passed(), "flipped": world.flipped,
        "stuck": not world.passed() and not world.flipped,
        "mode": the_plan.mode if the_plan else "none",
        "energy_J": energy, "k0": geometry.k0_nm_per_rad(),
        "t_contact_s": None if world.first_contact_us is None else world.first_contact_us * 1e-6,
        "t_end_s": world.t_us * 1e-6, "x_end_m": world.state.x_m,
        "max_roll_deg": math.degrees(peak[0]), "max_pitch_deg": math.degrees(peak[1]),
        "force_samples": len(samples),
    }
    if start_pose is not None:
        out["control_start"] = {"x_m": start_pose[0], "roll_deg": math.degrees(start_pose[1]),
                                "pitch_deg": math.degrees(start_pose[2])}
    if est is not None:
        out["estimate"] = est.as_dict()
    if the_plan is not None:
        out["barrier_J"], out["path_cost_J"] = the_plan.barrier_j, the_plan.path_cost_j
        out["plan_duration_s"] = the_plan.duration_s
    return out
