"""``hexhil demo``: what ``make demo`` runs."""
from __future__ import annotations

import argparse

from protocol import dynamixel


def run(args: argparse.Namespace) -> int:
    # The ROBOTIS manual's PING example, built and parsed back.
    pkt = dynamixel.ping(1)
    assert pkt == bytes.fromhex("FFFF010201FB"), pkt.hex()
    parsed = dynamixel.Parser().feed(pkt + dynamixel.status(1))
    print(f"protocol self-check: {len(parsed)} packets round-tripped; ok")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="set-up check and the main job")
    p.set_defaults(func=run)
