"""``hexhil beams estimate|plan|run``: seed 000's force sensing, planning and closed loop."""
from __future__ import annotations

import argparse
import math

import numpy as np

from hexhil.hil.scenario import check_seed
from hexhil.cli import JSON_HELP, OVERWRITE_HELP, actions, emit
from hexhil.protocol.errors import BadValue, UserError


def _nonneg(name: str, v: float) -> float:
    if not math.isfinite(v) or v < 0:
        raise BadValue(f"--{name} must be a finite number >= 0, got {v}")
    return v


def _stiffness(name: str, v: float) -> float:
    """A beam stiffness the world integrates faithfully: 0 up to the avoidance baseline's
    rigid beams (nodes.RIGID_K_NM_PER_RAD, 100 N m/rad). With a 1 N push into both beams,
    T + E - F_x x drifts 0.04 mJ at k = 100, 1.3 mJ at 1e4 and 52 J at 1e5: the 0.2 ms step
    no longer resolves the spring, and a run reports a made-up outcome."""
    from hexhil.papers.beam_traversal.nodes import RIGID_K_NM_PER_RAD

    if not (math.isfinite(v) and 0 <= v <= RIGID_K_NM_PER_RAD):
        raise BadValue(f"--{name} must be a stiffness in 0..{RIGID_K_NM_PER_RAD:g} N m/rad "
                       f"(seed 000: flimsy 0.01, stiff 0.25, rig 0.78; 100 is rigid), got {v}")
    return v


def cmd_estimate(args: argparse.Namespace) -> int:
    from hexhil.papers.beam_traversal.estimator import estimate
    from hexhil.papers.beam_traversal.push import push_samples

    k1, k2 = _stiffness("k1", args.k1), _stiffness("k2", args.k2)
    hb1 = _nonneg("hb-mm", args.hb_mm) * 1e-3
    hb2 = hb1 if args.hb2_mm is None else _nonneg("hb2-mm", args.hb2_mm) * 1e-3
    if not 10 <= args.sensing_ms <= 5000:
        raise BadValue(f"--sensing-ms must be in 10..5000, got {args.sensing_ms}")
    _nonneg("noise", args.noise)
    poses, forces = push_samples(k1, k2, hb1, hb2, args.noise, args.sensing_ms,
                                 check_seed(args.seed, "--seed"))
    if len(poses) < 2:
        raise UserError("too few force samples in the sensing window (no contact?)")
    est = estimate(poses, forces, args.unknowns, args.method)
    out = est.as_dict()
    out.update(samples=len(poses), true_k1=k1, true_k2=k2, true_hb1_mm=hb1 * 1e3, true_hb2_mm=hb2 * 1e3,
               noise=args.noise, unknowns=args.unknowns)
    emit(args, out, f"k1 = {est.k1:.4f} N m/rad (true {k1}), k2 = {est.k2:.4f} (true {k2}), "
                    f"h_b1 = {est.hb1_m * 1e3:.2f} mm, h_b2 = {est.hb2_m * 1e3:.2f} mm  "
                    f"[{args.method}, {len(poses)} samples, {est.elapsed_s * 1e3:.1f} ms]")
    return 0


def cmd_plan(args: argparse.Namespace) -> int:
    from hexhil.hil.world.beam_body import PAPER_BODY
    from hexhil.papers.beam_traversal import landscape, planner
    from hexhil.papers.beam_traversal.push import start_after_delay

    k1, k2 = _stiffness("k1", args.k1), _stiffness("k2", args.k2)
    hb = _nonneg("hb-mm", args.hb_mm) * 1e-3
    start = start_after_delay(k1, k2, hb, _nonneg("delay-ms", args.delay_ms))
    land = landscape.build(landscape.paper_grid(), hb, hb)
    p = planner.plan(land, k1, k2, start)
    out = {"mode": p.mode, "k0": PAPER_BODY.k0_nm_per_rad(), "barrier_J": p.barrier_j,
           "path_cost_J": p.path_cost_j, "vertices": len(p.path), "duration_s": p.duration_s,
           "start": {"x_m": start[0], "roll_deg": math.degrees(start[1]), "pitch_deg": math.degrees(start[2])},
           "max_roll_deg": float(np.degrees(np.abs(p.path[:, 1]).max())),
           "max_pitch_deg": float(np.degrees(np.abs(p.path[:, 2]).max()))}
    emit(args, out, f"mode {p.mode}: barrier {p.barrier_j * 1e3:.1f} mJ, path cost {p.path_cost_j * 1e3:.1f} mJ, "
                    f"{len(p.path)} vertices; k0 = {out['k0']:.4f} N m/rad")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from hexhil.papers.beam_traversal.beams_run import RunConfig, run
    from hexhil.trace.recorder import open_recorder

    hb = _nonneg("hb-mm", args.hb_mm) * 1e-3
    fx = args.fx if args.fx is not None else (1.0 if args.strategy == "none" else 0.1)
    if abs(fx) > 2.0:
        raise BadValue(f"--fx must be within the actuator limit |F_x| <= 2 N, got {fx}")
    cfg = RunConfig(_stiffness("k1", args.k1), _stiffness("k2", args.k2), hb, hb, args.strategy, fx,
                    _nonneg("noise", args.noise), _nonneg("delay-ms", args.delay_ms),
                    seed=check_seed(args.seed, "--seed"))
    meta = {"command": "beams run", "k1": cfg.k1, "k2": cfg.k2, "strategy": cfg.strategy, "seed": cfg.seed}
    rec = open_recorder(args.out, meta, overwrite=args.overwrite)
    try:
        out = run(cfg, recorder=rec)
    finally:
        if rec is not None:
            rec.close()
    what = "traversed" if out["traversed"] else ("flipped" if out["flipped"] else "stuck")
    emit(args, out, f"{cfg.strategy}: {what} (mode {out['mode']}), energy {out['energy_J'] * 1e3:.1f} mJ")
    return 0


def _beam_args(p: argparse.ArgumentParser, hb_mm: float | None = 0.0) -> None:
    """The beams every action needs: stiffnesses (N m/rad) and deflection height (mm; None:
    required)."""
    p.add_argument("--k1", type=float, required=True, metavar="K",
                   help="the first beam's stiffness in N m/rad, 0..100 (seed 000: flimsy 0.01, "
                        "stiff 0.25)")
    p.add_argument("--k2", type=float, required=True, metavar="K",
                   help="the second beam's stiffness in N m/rad, 0..100")
    p.add_argument("--hb-mm", type=float, default=hb_mm, required=hb_mm is None, metavar="MM",
                   help="height of the beams' deflection point above the ground in mm"
                        + (" (default 0)" if hb_mm is not None else ""))


def register(sub: argparse._SubParsersAction) -> None:
    bs = actions(sub, "beams", "force-sensing beam traversal (seed 000)")
    e = bs.add_parser("estimate", help="push into the beams, sense 100 Hz forces, estimate k and h_b")
    _beam_args(e, hb_mm=None)
    e.add_argument("--hb2-mm", type=float, metavar="MM",
                   help="the second beam's deflection height in mm (default: --hb-mm)")
    e.add_argument("--noise", type=float, required=True,
                   help="relative force noise, sigma of Eq. 6 (0.2 = 20 %%)")
    e.add_argument("--unknowns", type=int, choices=(2, 3, 4), required=True,
                   help="what to estimate: 2 = k1, k2 (h_b known 0); 3 = + one h_b for both; "
                        "4 = + h_b1, h_b2")
    e.add_argument("--sensing-ms", type=float, default=300.0, metavar="MS",
                   help="force samples from this long after first contact, in ms, 10..5000 "
                        "(default 300)")
    e.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    e.add_argument("--method", choices=("fast", "paper"), default="fast",
                   help="fast: bounded maximum likelihood (default); paper: Eq. 7 by "
                        "Nelder-Mead from 100 random starts")
    e.add_argument("--json", action="store_true", help=JSON_HELP)
    e.set_defaults(func=cmd_estimate)
    pl = bs.add_parser("plan", help="Eq. 8 landscape on the full grid + Dijkstra: pitch or roll")
    _beam_args(pl)
    pl.add_argument("--delay-ms", type=float, default=300.0, metavar="MS",
                    help="sensory delay: plan from the pose this long after first contact under "
                         "a 0.1 N push, in ms (default 300)")
    pl.add_argument("--json", action="store_true", help=JSON_HELP)
    pl.set_defaults(func=cmd_plan)
    r = bs.add_parser("run", help="closed loop over CAN: sense, estimate, plan, control")
    _beam_args(r)
    r.add_argument("--strategy", choices=("interact", "avoid", "none"), required=True,
                   help="interact: plan through the estimated beams; avoid: roll past them as "
                        "rigid obstacles; none: push with --fx, no control")
    r.add_argument("--fx", type=float, help="propulsion before control (N); default 1 for none, 0.1 otherwise")
    r.add_argument("--noise", type=float, default=0.2,
                   help="relative force noise, sigma of Eq. 6 (default 0.2 = 20 %%)")
    r.add_argument("--delay-ms", type=float, default=300.0, metavar="MS",
                   help="sensory delay from first contact to control, in ms (default 300)")
    r.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    r.add_argument("--out", metavar="FILE.mcap", help="record the CAN traffic to this MCAP file")
    r.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    r.add_argument("--json", action="store_true", help=JSON_HELP)
    r.set_defaults(func=cmd_run)
