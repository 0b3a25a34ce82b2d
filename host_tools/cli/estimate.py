"""``hexhil estimate FILE``: re-run the beam estimator on a trace's force frames.

Works on any trace with ``force`` and ``body_pose`` CAN frames: a simulated
``hexhil beams run --out`` or a physical robot's CSV brought in by ``hexhil trace
import-csv``. Each force sample is paired with the body pose logged at the same instant or, failing
that, the latest one before it; the
sensing window is the ``--sensing-s`` after the first sample whose force magnitude exceeds
``--contact-n`` (seed 000 Sec. II-E: T_s = 300 ms after first contact).
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from hexhil.cli import JSON_HELP, emit_json
from hexhil.protocol.errors import BadValue

SENSING_S = 0.300        # seed 000 Sec. II-E: T_s = 300 ms after first contact
CONTACT_N = 0.01         # |F| above this counts as contact (the frame's 1 mN step x 10)


def run(args: argparse.Namespace) -> int:
    from hexhil.papers.beam_traversal.estimator import estimate
    from hexhil.papers.beam_traversal.trace_samples import load_samples

    if args.sensing_s <= 0 or not math.isfinite(args.sensing_s):
        raise BadValue("--sensing-s must be a positive number of seconds")
    t, poses, forces, logged = load_samples(args.file, args.start, args.end)
    mag = np.linalg.norm(forces, axis=1)
    hit = np.flatnonzero(mag > args.contact_n)
    if hit.size == 0:
        raise BadValue(f"{args.file}: no force sample above {args.contact_n} N: no beam contact")
    t0 = t[hit[0]]
    window = (t >= t0) & (t < t0 + args.sensing_s)
    est = estimate(poses[window], forces[window], unknowns=args.unknowns, method=args.method)
    out = {"file": args.file, "first_contact_s": float(t0), "samples": int(window.sum()),
           "sensing_s": args.sensing_s, "unknowns": args.unknowns, **est.as_dict()}
    if logged is not None:
        out["logged_estimate"] = logged
    if args.json:
        emit_json(out)
    else:
        print(f"first contact at {t0:.3f} s; {out['samples']} samples in {args.sensing_s:g} s "
              f"({args.method}, {args.unknowns} unknowns)")
        print(f"k1 = {est.k1:.4f} N m/rad, k2 = {est.k2:.4f} N m/rad, "
              f"h_b1 = {est.hb1_m * 1e3:.3f} mm, h_b2 = {est.hb2_m * 1e3:.3f} mm, "
              f"Eq. 7 error {est.error_n:.4f} N")
        if logged is not None:
            print(f"logged estimate: k1 = {logged['k1']:.4f}, k2 = {logged['k2']:.4f} N m/rad, "
                  f"h_b = {logged['hb_mm']:.3f} mm, mode {logged['mode']}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("estimate", help="re-run the beam estimator on a trace's force frames")
    p.add_argument("file", help="MCAP trace with force and body_pose CAN frames")
    p.add_argument("--method", choices=("fast", "paper"), default="fast",
                   help="fast: Eq. 6 maximum likelihood (bounded); paper: Nelder-Mead on Eq. 7, 100 restarts")
    p.add_argument("--unknowns", type=int, choices=(2, 3, 4), default=4,
                   help="4: k1 k2 hb1 hb2; 3: one h_b; 2: h_b = 0 (Tables 1-3)")
    p.add_argument("--sensing-s", type=float, default=SENSING_S,
                   help="sensing window after first contact (default 0.3 s, Sec. II-E)")
    p.add_argument("--contact-n", type=float, default=CONTACT_N,
                   help="force magnitude that counts as first contact (N)")
    p.add_argument("--start", type=float, metavar="S", help="ignore frames before this time")
    p.add_argument("--end", type=float, metavar="S", help="ignore frames from this time on")
    p.add_argument("--json", action="store_true", help=JSON_HELP)
    p.set_defaults(func=run)
