"""Seed 000's host side as two nodes on the run's CAN bus (Sec. III-B to III-E).

* ``PlannerNode`` (every world step): collects the force samples from first contact,
  estimates the beams after the sensing window, and at the end of the sensory delay plans
  from the pose it last heard and publishes ``beam_estimate`` with the mode;
* ``ControllerNode`` (every 2 ms): pushes with F_x until there is a plan, then runs Eq. 9
  and sends ``actuator_command``.

The plan itself (a path of grid vertices) does not fit CAN frames, so the controller takes
it from the planner in-process, as one host program would.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np

from hexhil.hil.canbus.bus import Endpoint, message
from hexhil.hil.world.beam_body import PAPER_BODY, BeamParams, BodyGeometry
from hexhil.hil.world.beams import DT_US
from hexhil.hil.world.beams_node import CONTROL_PERIOD_US, MAX_TIME_S
from hexhil.papers.beam_traversal import estimator, landscape, planner
from hexhil.papers.beam_traversal.control import FeedbackLinearisation
from hexhil.protocol import can_frames

RIGID_K_NM_PER_RAD = 100.0     # the avoidance baseline's map: beams as obstacles to roll past


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
    max_time_s: float = MAX_TIME_S    # after first contact
    grid: landscape.Grid = field(default_factory=landscape.paper_grid)
    preload_nm: float = 0.0
    beam_mass_kg: float = 0.0


def _frames(port: Endpoint) -> list[tuple[str, dict]]:
    return [can_frames.decode(m.arbitration_id, bytes(m.data)) for m in port.frames()]


class PlannerNode:
    period_us = DT_US

    def __init__(self, port: Endpoint, cfg: RunConfig, geometry: BodyGeometry = PAPER_BODY,
                 x0_m: float = 0.0) -> None:
        self.port, self.cfg, self.geometry = port, cfg, geometry
        self.samples: list[tuple[int, tuple[float, float, float], tuple[float, float, float]]] = []
        self.pose = (x0_m, 0.0, 0.0)
        self.contact_us: int | None = None
        self.estimate: estimator.Estimate | None = None
        self.plan: planner.Plan | None = None
        self.controller: FeedbackLinearisation | None = None
        self.start_pose: tuple[float, float, float] | None = None
        self.delay_us = int(round(cfg.delay_ms * 1000))
        self.window_us = min(int(round(cfg.sensing_ms * 1000)), self.delay_us)

    def tick(self, t: int) -> None:
        cfg = self.cfg
        for name, sig in _frames(self.port):
            if name == "body_pose":
                self.pose = (sig["x_m"], sig["roll_rad"], sig["pitch_rad"])
            elif name == "force":
                f = (sig["fx_n"], sig["fy_n"], sig["fz_n"])
                if self.contact_us is None and any(f):
                    self.contact_us = t
                if self.contact_us is not None and t - self.contact_us < self.window_us:
                    self.samples.append((t, self.pose, f))
        if self.contact_us is None:
            return
        since = t - self.contact_us
        if cfg.strategy == "interact" and self.estimate is None and since >= self.window_us:
            self.estimate = estimator.estimate(np.array([p for _, p, _ in self.samples]),
                                               np.array([f for _, _, f in self.samples]),
                                               cfg.unknowns, cfg.method, self.geometry)
        if self.plan is None and ((cfg.strategy == "interact" and since >= self.delay_us)
                                  or cfg.strategy == "avoid"):
            self._plan(t)

    def _plan(self, t: int) -> None:
        cfg, est, g = self.cfg, self.estimate, self.geometry
        self.start_pose = self.pose
        if cfg.strategy == "interact":
            hb = 0.5 * (est.hb1_m + est.hb2_m) if cfg.unknowns == 3 else est.hb1_m
            land = landscape.build(cfg.grid, est.hb1_m, est.hb2_m, g)
            self.plan = planner.plan(land, est.k1, est.k2, self.start_pose)
            model = [BeamParams(est.k1, est.hb1_m), BeamParams(est.k2, est.hb2_m)]
            self.port.send(message(
                "beam_estimate", k1_nm_per_rad=est.k1, k2_nm_per_rad=est.k2, hb_m=hb,
                mode=can_frames.MODE_NAMES.index(self.plan.mode)))
        else:
            land = landscape.build(cfg.grid, 0.0, 0.0, g)
            self.plan = planner.plan(land, RIGID_K_NM_PER_RAD, RIGID_K_NM_PER_RAD, self.start_pose)
            model = []                  # a geometric map knows no beam forces
        self.controller = FeedbackLinearisation(self.plan, t, model, g)


class ControllerNode:
    period_us = CONTROL_PERIOD_US

    def __init__(self, port: Endpoint, planner_node: PlannerNode, fx_n: float,
                 x0_m: float = 0.0, vx0_m_s: float = 0.0) -> None:
        self.port, self.planner, self.fx_n = port, planner_node, fx_n
        self.pose = (x0_m, 0.0, 0.0)
        self.rate = (vx0_m_s, 0.0, 0.0)

    def tick(self, t: int) -> None:
        for name, sig in _frames(self.port):
            if name == "body_pose":
                self.pose = (sig["x_m"], sig["roll_rad"], sig["pitch_rad"])
            elif name == "body_rate":
                self.rate = (sig["vx_m_s"], sig["roll_rate_rad_s"], sig["pitch_rate_rad_s"])
        ctl = self.planner.controller
        u = ctl(t, self.pose, self.rate) if ctl is not None else (self.fx_n, 0.0, 0.0)
        self.port.send(message("actuator_command", fx_n=u[0], tau1_nm=u[1],
                               tau2_nm=u[2]))
