"""The closed loop of Sec. III-C/D/E: the beams world and the host nodes on one CAN bus,
run by the lockstep simulator (hil/sim.py) like every other run.

``run(cfg)`` is what ``hexhil beams run``, the experiments and ``hexhil run`` of a beams
scenario call; ``config_from_scenario`` reads a scenario's ``[beams]`` and ``[traversal]``.
"""
from __future__ import annotations

import math
from typing import Any

from hil.sim import Simulator
from hil.world.beam_body import PAPER_BODY, BeamParams, BodyGeometry
from hil.world.beams import BeamsWorld, BodyState
from hil.world.beams_node import NO_CONTACT_LIMIT_US, BeamsNode
from host_tools.traversal.nodes import ControllerNode, PlannerNode, RunConfig
from protocol.errors import UserError

STRATEGIES = ("interact", "avoid", "none")
METHODS = ("fast", "paper")


def config_from_scenario(sc: dict[str, Any], seed: int) -> RunConfig:
    """A checked beams scenario's ``[beams]`` and ``[traversal]`` as a run configuration."""
    b, t, where = sc["beams"], sc["traversal"], sc["_path"]
    for key in ("k1_nm_per_rad", "k2_nm_per_rad"):
        if key not in b:
            raise UserError(f"{where}: world.kind 'beams' needs key 'beams.{key}'")
    for key, value in b.items():
        if not (math.isfinite(value) and value >= 0):
            raise UserError(f"{where}: key 'beams.{key}' must be a finite number >= 0, "
                            f"got {value}")
    strategy = t.get("strategy", "interact")
    if strategy not in STRATEGIES:
        raise UserError(f"{where}: key 'traversal.strategy' must be one of "
                        f"{', '.join(STRATEGIES)}, got {strategy!r}")
    if t.get("method", "fast") not in METHODS:
        raise UserError(f"{where}: key 'traversal.method' must be fast or paper")
    if t.get("unknowns", 3) not in (2, 3, 4):
        raise UserError(f"{where}: key 'traversal.unknowns' must be 2, 3 or 4")
    fx = t.get("fx_n", 1.0 if strategy == "none" else 0.1)
    if abs(fx) > 2.0:
        raise UserError(f"{where}: key 'traversal.fx_n' must be within the actuator limit "
                        f"|F_x| <= 2 N, got {fx}")
    hb1 = b.get("hb1_m", 0.0)
    return RunConfig(b["k1_nm_per_rad"], b["k2_nm_per_rad"], hb1, b.get("hb2_m", hb1),
                     strategy, fx, b.get("noise", 0.2), t.get("delay_ms", 300.0),
                     t.get("sensing_ms", 300.0), t.get("unknowns", 3), t.get("method", "fast"),
                     seed, t.get("max_time_s", 8.0), preload_nm=b.get("preload_nm", 0.0),
                     beam_mass_kg=b.get("mass_kg", 0.0))


def run(cfg: RunConfig, recorder: Any = None, geometry: BodyGeometry = PAPER_BODY,
        can_server: Any = None, scene: bool = False, realtime: bool = False) -> dict:
    """One traversal; returns the outcome, the estimate, the plan and the Eq. 11 energy.
    ``scene``/``realtime``: as ``hil.sim.Simulator`` takes them."""
    if cfg.strategy not in STRATEGIES:
        raise ValueError(f"unknown strategy {cfg.strategy!r}")
    truth = [BeamParams(cfg.k1, cfg.hb1_m, cfg.preload_nm, cfg.beam_mass_kg),
             BeamParams(cfg.k2, cfg.hb2_m, cfg.preload_nm, cfg.beam_mass_kg)]
    state = BodyState()
    world = BeamsNode(BeamsWorld(truth, geometry, state, noise=cfg.noise, seed=cfg.seed),
                      cfg.max_time_s)
    scenario = {"world": {"kind": "beams"}, "_path": "<beams run>"}
    sim = Simulator(scenario, cfg.seed, world=world, recorder=recorder, can_server=can_server,
                    scene=scene, realtime=realtime)
    plan = PlannerNode(sim.can.endpoint("tx"), cfg, geometry, state.x_m)
    sim.add_node(plan)
    sim.add_node(ControllerNode(sim.can.endpoint("rx"), plan, cfg.fx_n, state.x_m, state.vx_m_s))
    result = sim.run(NO_CONTACT_LIMIT_US * 1e-6 + cfg.max_time_s + 1.0)
    w = result.world
    out = {
        "strategy": cfg.strategy, "k1": cfg.k1, "k2": cfg.k2, "hb1_mm": cfg.hb1_m * 1e3,
        "hb2_mm": cfg.hb2_m * 1e3, "fx_n": cfg.fx_n, "noise": cfg.noise, "delay_ms": cfg.delay_ms,
        "seed": cfg.seed, "traversed": w["traversed"], "flipped": w["flipped"], "stuck": w["stuck"],
        "mode": plan.plan.mode if plan.plan else "none", "energy_J": w["energy_J"], "k0": w["k0"],
        "t_contact_s": w["t_contact_s"], "t_end_s": w["t_end_s"], "x_end_m": w["x_end_m"],
        "max_roll_deg": w["max_roll_deg"], "max_pitch_deg": w["max_pitch_deg"],
        "force_samples": len(plan.samples),
    }
    if plan.start_pose is not None:
        x, roll, pitch = plan.start_pose
        out["control_start"] = {"x_m": x, "roll_deg": math.degrees(roll),
                                "pitch_deg": math.degrees(pitch)}
    if plan.estimate is not None:
        out["estimate"] = plan.estimate.as_dict()
    if plan.plan is not None:
        out["barrier_J"], out["path_cost_J"] = plan.plan.barrier_j, plan.plan.path_cost_j
        out["plan_duration_s"] = plan.plan.duration_s
    return out
