"""``hexhil model urdf|mjcf``: the hexapod's robot description on stdout, generated from
``protocol/hexapod.py`` (the URDF by host_tools/robot_model.py, the MJCF the simulated world
itself loads, from hil/world/hexapod_world.py)."""
from __future__ import annotations

import argparse
import sys

from hexhil.cli import actions


def _urdf(args: argparse.Namespace) -> int:
    from hexhil.robot_model import urdf

    sys.stdout.write(urdf())
    return 0


def _mjcf(args: argparse.Namespace) -> int:
    from hexhil.hil import scenario as scenario_mod
    from hexhil.hil.run.rig import make_world
    from hexhil.hil.world.hexapod_world import RobotParams, mjcf

    if args.scenario:
        sc = scenario_mod.load_scenario(args.scenario)
        seed = (sc.scenario.seed if args.seed is None
                else scenario_mod.check_seed(args.seed, "--seed"))
        xml = make_world(sc, seed).xml
    else:
        xml = mjcf(RobotParams(), [], 1.0)
    sys.stdout.write(xml)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    kinds = actions(sub, "model", "the hexapod's robot description (URDF, MJCF)", "KIND",
                        __doc__)
    u = kinds.add_parser("urdf", help="URDF (joints as the MJCF: angle = servo angle)",
                         description="The hexapod as a URDF on stdout, for RViz, Foxglove's URDF "
                                     "layer or robotics libraries: generated from "
                                     "protocol/hexapod.py like the MuJoCo world, with its zero "
                                     "pose and axes, so a joint angle is the servo angle (0 at "
                                     "the AX-12's centre); each leg ends in a <leg>_foot link. "
                                     "Example: hexhil model urdf > hexapod.urdf")
    u.set_defaults(func=_urdf)
    m = kinds.add_parser("mjcf", help="the MJCF the simulated world loads")
    m.add_argument("--scenario", metavar="FILE.toml",
                   help="with this scenario's obstacles and ground friction (default: flat)")
    m.add_argument("--seed", type=int, help="terrain seed (default: the scenario's)")
    m.set_defaults(func=_mjcf)
