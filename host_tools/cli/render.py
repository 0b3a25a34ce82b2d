"""``hexhil render TRACE.mcap --out run.gif|run.mp4|frame.png``: a recorded hexapod run
replayed into MuJoCo's offscreen renderer (host_tools/render.py)."""
from __future__ import annotations

import argparse


def _render(args: argparse.Namespace) -> int:
    from hexhil import render as render_mod
    from hexhil.cli import ProgressBar

    backend = render_mod.choose_gl()  # before MuJoCo is imported
    n = render_mod.render(args.trace, args.out, args.camera, args.fps, args.width, args.height,
                          args.at, ProgressBar("frame"), args.overwrite)
    print(f"{args.out}: {n} frame{'s' if n != 1 else ''} ({backend})")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    from hexhil.render import CAMERAS

    p = sub.add_parser("render", help="render a trace's ground truth to a video or PNG",
                       description=__doc__)
    p.add_argument("trace", help="an MCAP trace of a hexapod run (hexhil run --out)")
    p.add_argument("--out", required=True, metavar="FILE",
                   help="run.gif, run.mp4, or frame.png (one frame: --at, default the middle)")
    p.add_argument("--camera", choices=CAMERAS, default="follow",
                   help="follow: behind the body on its left, from above; "
                        "side: from the left, level")
    p.add_argument("--fps", type=float, default=30.0,
                   help="frames a second, up to 100 (default 30)")
    p.add_argument("--width", type=int, default=480, help="pixels (default 480)")
    p.add_argument("--height", type=int, default=360, help="pixels (default 360)")
    p.add_argument("--at", type=float, metavar="S", help="the PNG's time in the trace (s)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a file that already exists (without it, it is refused)")
    p.set_defaults(func=_render)
