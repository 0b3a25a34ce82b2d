"""scenarios/flat-tripod-xl430.toml: our firmware drives 18 emulated XL430s in Protocol 2.0
(one SYNC_READ of all 18 a cycle) and the hexapod walks."""
from __future__ import annotations

import json

from conftest import hexhil_in_process


def test_flat_tripod_on_xl430s_walks_half_a_metre_with_one_sync_read_a_cycle() -> None:
    r = hexhil_in_process("run", "scenarios/flat-tripod-xl430.toml", "--json")
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    d = json.loads(r.stdout.strip().splitlines()[-1])
    assert d["state"] == "walking" and d["stop_reason"] is None, d
    assert d["body"]["dx_m"] >= 0.5, d["body"]
    # one SYNC_WRITE (176 bytes) and one SYNC_READ (32 bytes out, 18 x 21 back): 5.86 ms of
    # wire a cycle at 1 Mbps, a little more when stuffing lengthens a reply
    assert 5_600 <= d["bus_wire_min_per_cycle_us"] < 6_100, d["bus_wire_min_per_cycle_us"]
