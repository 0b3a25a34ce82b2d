"""The closed loop of Sec. III-C/D/E: the beams world and the host nodes on one CAN bus,
run by the lockstep simulator (hil/run/lockstep.py) like every other run.

``run(cfg)`` is what ``hexhil beams run``, the experiments and ``hexhil run`` of a beams
scenario call; ``config_from_scenario`` reads a scenario's ``[beams]`` and ``[traversal]``.
"""
from __future__ import annotations

import math
import time

from hexhil.hil.run_result import RunResult
from hexhil.hil.scenario import Scenario, parse
from hexhil.hil.seams import CanGateway, TraceRecorder
from hexhil.hil.scenario.beams import STRATEGIES
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.world.beam_body import PAPER_BODY, BeamParams, BodyGeometry
from hexhil.hil.world.beams import BeamsWorld, BodyState
from hexhil.hil.world.beams_node import NO_CONTACT_LIMIT_US, BeamsNode
from hexhil.papers.beam_traversal.nodes import ControllerNode, PlannerNode, RunConfig



def config_from_scenario(sc: Scenario, seed: int) -> RunConfig:
    """A beams scenario's ``[beams]`` and ``[traversal]`` (checked, with their defaults:
    hil/scenario/beams.py) as a run configuration."""
    b, t = sc.beams, sc.traversal
    return RunConfig(b.k1_nm_per_rad, b.k2_nm_per_rad, b.hb1_m, b.hb2_m, t.strategy, t.fx_n,
                     b.noise, t.delay_ms, t.sensing_ms, t.unknowns, t.method, seed,
                     t.max_time_s, preload_nm=b.preload_nm, beam_mass_kg=b.mass_kg)


def run(cfg: RunConfig, recorder: TraceRecorder | None = None,
        geometry: BodyGeometry = PAPER_BODY, can_server: CanGateway | None = None,
        scene: bool = False, realtime: bool = False, scenario: Scenario | None = None) -> dict:
    """One traversal; returns the outcome, the estimate, the plan and the Eq. 11 energy.
    ``scene``/``realtime``: as ``hil.run.lockstep.Simulator`` takes them; ``scenario`` (the file
    ``cfg`` came from) gives the run its CAN faults, else none."""
    if cfg.strategy not in STRATEGIES:
        raise ValueError(f"unknown strategy {cfg.strategy!r}")
    truth = [BeamParams(cfg.k1, cfg.hb1_m, cfg.preload_nm, cfg.beam_mass_kg),
             BeamParams(cfg.k2, cfg.hb2_m, cfg.preload_nm, cfg.beam_mass_kg)]
    state = BodyState()
    world = BeamsNode(BeamsWorld(truth, geometry, state, noise=cfg.noise, seed=cfg.seed),
                      cfg.max_time_s)
    sim = Simulator(scenario or parse({}, "<beams run>"), cfg.seed, world=world, recorder=recorder, can_server=can_server,
                    scene=scene, realtime=realtime)
    plan = PlannerNode(sim.can.endpoint("tx"), cfg, geometry, state.x_m)
    sim.add_node(plan)
    sim.add_node(ControllerNode(sim.can.endpoint("rx"), plan, cfg.fx_n, state.x_m, state.vx_m_s))
    result = sim.run(NO_CONTACT_LIMIT_US * 1e-6 + cfg.max_time_s + 1.0)
    w = result.world
    out = {
        "strategy": cfg.strategy, "k1": cfg.k1, "k2": cfg.k2, "hb1_mm": cfg.hb1_m * 1e3,
        "hb2_mm": cfg.hb2_m * 1e3, "fx_n": cfg.fx_n, "noise": cfg.noise, "delay_ms": cfg.delay_ms,
        "seed": cfg.seed, "traversed": w.traversed, "flipped": w.flipped, "stuck": w.stuck,
        "mode": plan.plan.mode if plan.plan else "none", "energy_J": w.energy_J, "k0": w.k0,
        "t_contact_s": w.t_contact_s, "t_end_s": w.t_end_s, "x_end_m": w.x_end_m,
        "max_roll_deg": w.max_roll_deg, "max_pitch_deg": w.max_pitch_deg,
        "force_samples": len(plan.samples),
    }
    if result.faults:
        out["faults"] = dict(result.faults)   # [faults] force_bias, force_dropout
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


def run_scenario(sc: Scenario, seed: int, recorder: TraceRecorder | None,
                 can_server: CanGateway | None, scene: bool, realtime: bool) -> RunResult:
    """A beams scenario's traversal as ``hexhil run`` and ``host_tools.Run`` run it (the
    plug-in this package registers): the outcome in the result's ``host_nodes``."""
    wall0 = time.perf_counter()
    out = run(config_from_scenario(sc, seed), recorder, can_server=can_server, scene=scene,
              realtime=realtime, scenario=sc)
    return RunResult("none", sim_time_s=out["t_end_s"],
                     wall_time_s=time.perf_counter() - wall0,
                     faults=out.pop("faults", {}), host_nodes=out)
