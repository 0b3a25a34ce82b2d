"""Link version 2 (docs/link.md "R reads"): our firmware sends a cycle's status reads in one
exchange, and the host retries and skips them as the firmware's master would. A run of it
puts the same bytes on the servo bus at the same times as a version 1 run (a firmware
that offers only version 1), with the same trace but for the /link topic, in fewer round
trips; its trace replays."""
from __future__ import annotations

import random
from collections import defaultdict
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hexhil.firmware.fault_policy import FaultPolicy
from hexhil.hil import scenario
from hexhil.hil.link.firmware_process import firmware_command
from hexhil.hil.run.lockstep import Simulator
from hexhil import replay
from hexhil.trace import recorder as rec
from mpy import ROOT

V1_CLIENT = "tests/link_clients/firmware_base_link.py"
DURATION_S = 2.0


def _run(path: Path, command: list[str]) -> tuple[str, int]:
    sc = scenario.load_scenario(ROOT / "scenarios" / "faults.toml")   # echo, bit errors, unplugs
    with rec.Recorder(path, {"scenario": "faults", "seed": 3}) as r:
        result = Simulator(sc, seed=3, recorder=r).run(duration_s=DURATION_S, command=command)
    assert result.exit_code == 0 and result.cycles > 50
    return result.serial_digest, result.round_trips


def _topics(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    out = defaultdict(list)
    with open(path, "rb") as f:
        for _, channel, m in make_reader(f).iter_messages():
            out[channel.topic].append((m.log_time, m.data))
    return out


def test_version_2_puts_the_same_bytes_on_the_bus_in_fewer_round_trips(tmp_path):
    mpy = firmware_command("micropython")
    v1 = _run(tmp_path / "v1.mcap", mpy[:-2] + [V1_CLIENT])
    v2 = _run(tmp_path / "v2.mcap", mpy)
    assert v1[0] == v2[0]
    assert v2[1] < 0.75 * v1[1]
    t1, t2 = _topics(tmp_path / "v1.mcap"), _topics(tmp_path / "v2.mcap")
    assert "/serial" in t1 and t1.keys() == t2.keys()
    assert [t for t in t1 if t1[t] != t2[t]] == ["/link"]
    result = replay.replay_firmware(tmp_path / "v2.mcap")
    assert result.identical and result.exchanges > 50


class _Master:
    """Answers each read with a scripted outcome; logs the servo IDs read."""

    def __init__(self, rng: random.Random) -> None:
        self.rng, self.log = rng, []

    def read_present(self, dev_id: int, board: object) -> bool:
        self.log.append(dev_id)
        return self.rng.random() < 0.6


def _reference(policy: FaultPolicy, master: _Master) -> None:
    """FaultPolicy.read_rotating as it was before the plan (one read after the other)."""
    budget = policy.reads_per_cycle
    retry = policy.suspect
    policy.suspect = []
    for k in retry[:budget]:
        if not master.read_present(policy.ids[k], None):
            policy.suspect.append(k)
    policy.suspect.extend(retry[budget:])
    budget -= min(len(retry), budget)
    while budget > 0:
        k = policy.cursor
        policy.cursor = (k + 1) % 18
        budget -= 1
        if k in policy.suspect:
            continue
        if not master.read_present(policy.ids[k], None):
            policy.suspect.append(k)


@pytest.mark.parametrize("reads_per_cycle", [1, 3, 7, 40])
def test_the_plan_reads_what_one_read_after_the_other_read(reads_per_cycle):
    cfg = {"servo_lost_s": 1.0, "critical_errors": 3, "reads_per_cycle": reads_per_cycle}
    ids = list(range(1, 19))
    for seed in range(30):
        ref, new = FaultPolicy(ids, cfg), FaultPolicy(ids, cfg)
        m_ref, m_new = _Master(random.Random(seed)), _Master(random.Random(seed))

        def many(reads, board, m=m_new):
            out = []
            for dev_id, skip in reads:
                out.append(None if skip >= 0 and out[skip] is not True
                           else m.read_present(dev_id, board))
            return out

        m_new.read_present_many = many
        for _ in range(40):
            _reference(ref, m_ref)
            new.read_rotating(m_new, None)
            assert (new.suspect, new.cursor, m_new.log) == (ref.suspect, ref.cursor, m_ref.log)
