"""``hexhil demo``: what ``make demo`` runs: the whole stack once, end to end.

1. The hexapod firmware, under the real ``micropython`` binary, walks seed 003's
   low-density terrain in MuJoCo with its tactile switches on and, on the same terrain and
   seed, with them ignored (the paper's baseline). The tactile run is recorded to MCAP.
2. The recording is summarised (topics, schemas, message counts).
3. Seed 000's robot senses flimsy and stiff beams, plans a mode and traverses under
   feedback control over the simulated CAN bus.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from hexhil.cli import JSON_HELP, emit_json

SCENARIO = "scenarios/obstacles-low-small.toml"


def _walks(out_dir: Path) -> dict:
    from hexhil.run_summary import run

    trace = out_dir / "tactile.mcap"
    with_method, _ = run(SCENARIO, out=str(trace), overwrite=True)   # the demo's folder
    without, _ = run(SCENARIO, tactile=False)
    for label, s in (("tactile on ", with_method), ("tactile off", without)):
        b = s["body"]
        print(f"  {label}: dx {b['dx_m']:+.3f} m of {s['commanded_distance_m']:.3f} m commanded, "
              f"dy {b['dy_m']:+.3f} m, dyaw {b['dyaw_deg']:+.1f} deg, "
              f"{s['switch_edges']} switch edges, {s['trajectory_changes']} trajectory changes "
              f"({s['real_time_factor']:.0f}x real time)")
    return {"tactile": with_method, "no_tactile": without, "trace": str(trace)}


def _trace_summary(path: str) -> dict:
    from hexhil.trace.reader import info

    summary = info(path)
    print(f"  {summary['file']}: {summary['messages']} messages on {len(summary['topics'])} topics, "
          f"{summary['duration_s']:.1f} s, {', '.join(summary['compression'])} chunks")
    for t in summary["topics"][:12]:
        print(f"    {t['topic']:<28} {t['messages']:>7}  {t['schema']}")
    return summary


def _beams() -> dict:
    from hexhil.papers.beam_traversal.beams_run import RunConfig, run

    out = {}
    for label, k in (("flimsy", 0.01), ("stiff", 0.25)):
        r = run(RunConfig(k1=k, k2=k, strategy="interact", fx_n=0.1, seed=0))
        what = "traversed" if r["traversed"] else ("flipped" if r["flipped"] else "stuck")
        print(f"  {label} beams (k = {k} N m/rad): planned {r['mode']}, {what}, "
              f"energy {r['energy_J'] * 1e3:.1f} mJ")
        out[label] = r
    return out


def run(args: argparse.Namespace) -> int:
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    print(f"1. hexapod firmware (micropython) on {SCENARIO}, with and without tactile switching")
    walks = _walks(out_dir)
    print(f"2. the tactile run's trace ({walks['trace']})")
    trace = _trace_summary(walks["trace"])
    print("3. force sensing: estimate beam stiffness, plan, traverse (seed 000)")
    beams = _beams()
    nearer = walks["tactile"]["body"]["dx_m"] > walks["no_tactile"]["body"]["dx_m"]
    print(f"demo done: tactile switching {'reached further' if nearer else 'did NOT reach further'}; "
          f"trace in {walks['trace']}")
    if args.json:
        emit_json({"walks": {k: walks[k]["body"] for k in ("tactile", "no_tactile")},
                   "trace": walks["trace"], "trace_messages": trace["messages"],
                   "beams": {k: {"mode": v["mode"], "traversed": v["traversed"],
                                 "energy_J": v["energy_J"]} for k, v in beams.items()}})
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="the whole stack once, end to end (what `make demo` runs)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="out/demo", help="folder for the demo's trace")
    p.add_argument("--json", action="store_true", help=JSON_HELP)
    p.set_defaults(func=run)
