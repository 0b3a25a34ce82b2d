"""The bus fuzzer (docs/fuzzing.md): its fault kinds on the line and the CAN bus, its
mutations and shrinking, and the acceptance campaign: a planted bug in a variant of our
firmware (tests/fuzz_targets/trusting_ids.py) found, shrunk and replayed by ``hexhil test``;
our firmware survives the same campaign."""
from __future__ import annotations

import json
import os
import random
from dataclasses import replace
from pathlib import Path

import pytest

from hexhil.hil.clock import VirtualClock
from hexhil.hil.canbus.bus import CanBus
from hexhil.hil.scenario.faults_section import FaultEntry, FaultKind, FaultsConfig
from hexhil.hil.servobus.faults import Faults
from hexhil.bus_fuzz import campaign
from hexhil.bus_fuzz.execution import Execution
from hexhil.bus_fuzz.mutations import DEFAULT_KINDS, Mutation, Mutator, Vocabulary
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil, hexhil_in_process

TARGETS = ROOT / "tests" / "fuzz_targets"
CASE = TARGETS / "no-exception.toml"
PLANTED = TARGETS / "trusting_ids.py"
STATUS = dxl.status(3, 0, b"\x10\x02")          # servo 3's reply to a 2-byte READ


def faults_on(kind: FaultKind, **keys) -> Faults:
    """Faults whose one entry of ``kind`` is active from t = 0."""
    entry = {"at_s": 0.0, "until_s": 1.0, **keys}
    f = Faults(FaultsConfig(**{kind.value: (FaultEntry.parse(kind, entry, "test"),)}))
    f.start(VirtualClock(), 0)
    f.apply_due(0)
    return f


def parsed(data: bytes) -> tuple[int, int, bytes] | None:
    """(id, error, params) of the one status packet in ``data``, None if it is not one."""
    p = dxl.Parser()
    got = [(p.id, p.code, bytes(p.buf[5:5 + p.nparams])) for b in data if p.push(b)]
    return got[0] if len(got) == 1 else None


@pytest.mark.parametrize("kind,keys,expect", [
    (FaultKind.STATUS_CHECKSUM, {}, None),
    (FaultKind.STATUS_WRONG_ID, {"as_id": 200}, (200, 0, b"\x10\x02")),
    (FaultKind.STATUS_TRUNCATED, {}, None),
    (FaultKind.STATUS_PADDED, {}, (3, 0, b"\x10\x02\x00")),
    (FaultKind.STATUS_ERROR, {"bits": 0x20}, (3, 0x20, b"\x10\x02")),
])
def test_a_status_fault_mangles_the_servos_reply(kind, keys, expect):
    f = faults_on(kind, id=3, **keys)
    [(t, data)] = f.status_bursts(3, bytearray(STATUS), 500, 80)
    assert t == 500 and bytes(data) != STATUS and parsed(bytes(data)) == expect
    assert f.status_bursts(4, bytearray(STATUS), 500, 80) == [(500, bytearray(STATUS))]


def test_a_status_is_late_missing_or_doubled():
    assert faults_on(FaultKind.STATUS_LATE, id=3, delay_s=0.002).status_bursts(
        3, bytearray(STATUS), 500, 80) == [(2500, bytearray(STATUS))]
    assert faults_on(FaultKind.STATUS_MISSING, id=3).status_bursts(
        3, bytearray(STATUS), 500, 80) == []
    assert faults_on(FaultKind.STATUS_TWIN, id=3).status_bursts(
        3, bytearray(STATUS), 500, 80) == [(500, bytearray(STATUS)), (580, bytearray(STATUS))]


STATUS2 = dx2.status(3, 0, b"\x10\x02")       # the same reply in Protocol 2.0


def parsed2(data: bytes) -> tuple[int, int, bytes] | None:
    """(id, error, params after the error) of the one 2.0 status in ``data``, or None."""
    got = dx2.Parser().feed(bytes(data))
    return (got[0].id, got[0].error, bytes(got[0].params[1:])) if len(got) == 1 else None


@pytest.mark.parametrize("kind,keys,expect", [
    (FaultKind.STATUS_CHECKSUM, {}, None),
    (FaultKind.STATUS_WRONG_ID, {"as_id": 200}, (200, 0, b"\x10\x02")),
    (FaultKind.STATUS_TRUNCATED, {}, None),
    (FaultKind.STATUS_PADDED, {}, (3, 0, b"\x10\x02\x00")),
    *((FaultKind.STATUS_ERROR, {"bits": b}, (3, b, b"\x10\x02")) for b in (1, 2, 3, 4, 5, 6, 7, 128)),
    (FaultKind.STATUS_ERROR, {"bits": 0x84}, (3, 0x84, b"\x10\x02")),
])
def test_a_status_fault_mangles_a_protocol_2_reply(kind, keys, expect):
    f = faults_on(kind, id=3, **keys)
    [(t, data)] = f.status_bursts(3, bytearray(STATUS2), 500, 80, protocol=2)
    assert t == 500 and bytes(data) != STATUS2 and parsed2(data) == expect
    assert parsed2(STATUS2) == (3, 0, b"\x10\x02")


def test_status_faults_on_a_protocol_2_line_late_missing_twin_and_the_group_read():
    from hexhil.hil.servobus.protocols.v2 import Bus2
    from hexhil.hil.servobus.xseries_servo import XSeriesServo
    from hexhil.protocol.dynamixel import xl430 as xl

    def line(kind, **keys) -> Bus2:
        entry = FaultEntry.parse(kind, {"id": 1, "at_s": 0.0, "until_s": 1.0, **keys}, "t")
        servos = [XSeriesServo(i) for i in (1, 2)]
        for s in servos:
            s.table[xl.BAUD_RATE], s.table[xl.RETURN_DELAY_TIME] = 3, 0     # 1 Mbps, no delay
        return Bus2(servos, VirtualClock(), faults=Faults(FaultsConfig(**{kind.value: (entry,)})))

    def heard(bus: Bus2, pkt: bytes, timeout_us: int = 5000) -> list:
        bus.master_write(pkt)
        return dx2.Parser().feed(bus.master_read(4096, timeout_us))

    read1 = dx2.read(1, xl.PRESENT_POSITION, 4)
    assert [p.id for p in heard(line(FaultKind.STATUS_TWIN), read1)] == [1, 1]
    assert heard(line(FaultKind.STATUS_MISSING), read1) == []
    assert [p.id for p in heard(line(FaultKind.STATUS_WRONG_ID, as_id=7), read1)] == [7]
    late = line(FaultKind.STATUS_LATE, delay_s=0.002)
    assert heard(late, read1, 1000) == [] and [p.id for p in heard(late, b"", 5000)] == [1]
    # a group read: servo 1's reply garbled, servo 2's answered after it as ever
    bad = line(FaultKind.STATUS_CHECKSUM)
    got = heard(bad, dx2.sync_read(xl.PRESENT_POSITION, 4, [1, 2]))
    assert [p.id for p in got] == [2]


def test_the_mutator_draws_the_error_byte_of_the_lines_protocol():
    def drawn(protocol: int) -> set[int]:
        m = Mutator(Vocabulary((FaultKind.STATUS_ERROR,), (1, 2), 1.0, 3.0,
                               protocol=protocol), random.Random(5))
        return {m.fault().entry()["bits"] for _ in range(200)}
    assert drawn(1) <= set(range(1, 128)) and {1, 64} <= drawn(1)
    two = drawn(2)
    assert {1, 7, 128} <= two and all(b & 0x7F <= 7 for b in two) and any(b > 128 for b in two)


def test_status_faults_end_at_until_s():
    f = faults_on(FaultKind.STATUS_MISSING, id=3)
    f.apply_due(1_000_000)
    assert f.status_bursts(3, bytearray(STATUS), 1_000_500, 80) == [
        (1_000_500, bytearray(STATUS))]
    assert f.counts == {"status_missing": 1, "status_missing_end": 1}


def can_bus(kind: FaultKind, **keys) -> tuple[CanBus, list, VirtualClock]:
    f = faults_on(kind, **keys)
    clock = f._clock
    bus = CanBus(clock)
    bus.faults = f
    got = bus.endpoint("rx")
    return bus, got, clock


def frames(endpoint) -> list[tuple[int, bytes, int]]:
    return [(m.arbitration_id, bytes(m.data), round(m.timestamp * 1e6))
            for m in endpoint.frames()]


def test_can_faults_drop_garble_delay_and_swap_frames():
    bus, got, clock = can_bus(FaultKind.CAN_DROPPED)
    bus.send(0x100, b"\x01\x02", direction="tx")
    assert frames(got) == []
    bus, got, clock = can_bus(FaultKind.CAN_CORRUPT)
    bus.send(0x100, b"\x01\x02\x03\x04", direction="tx")
    [(arb_id, data, _)] = frames(got)
    assert arb_id == 0x100 and len(data) == 4 and data != b"\x01\x02\x03\x04"
    bus, got, clock = can_bus(FaultKind.CAN_DELAYED, delay_s=0.05)
    bus.send(0x100, b"\x01", direction="tx")
    clock.advance_to(49_000)
    bus.poll()
    assert frames(got) == []
    clock.advance_to(50_000)
    bus.poll()
    assert frames(got) == [(0x100, b"\x01", 50_000)]
    bus, got, clock = can_bus(FaultKind.CAN_REORDERED)
    bus.send(0x100, b"\x01", direction="tx")
    assert frames(got) == []                              # the first waits for the next
    bus.send(0x101, b"\x02", direction="tx")
    bus.send(0x102, b"\x03", direction="tx")
    bus.faults.can_faults.clear()
    bus.send(0x103, b"\x04", direction="tx")
    assert [f[0] for f in frames(got)] == [0x101, 0x100, 0x103, 0x102]


def test_a_fault_key_out_of_range_is_one_line():
    with pytest.raises(UserError, match="bits' must be 1-255"):
        FaultEntry.parse(FaultKind.STATUS_ERROR, {"id": 1, "at_s": 1.0, "bits": 256}, "t")
    with pytest.raises(UserError, match="delay_s' must be in"):
        FaultEntry.parse(FaultKind.STATUS_LATE, {"id": 1, "at_s": 1.0, "delay_s": 0}, "t")


def test_mutations_are_seeded_and_stay_in_the_window():
    vocab = Vocabulary(DEFAULT_KINDS, tuple(range(1, 19)), 1.0, 3.0)
    draws = [[m.fresh() for _ in range(50)]
             for m in (Mutator(vocab, random.Random(7)), Mutator(vocab, random.Random(7)))]
    assert draws[0] == draws[1]
    faults = [m for i in draws[0] for m in i]
    assert {m.kind for m in faults} >= {FaultKind.STATUS_WRONG_ID, FaultKind.SWITCH_STUCK}
    assert all(1.0 <= m.at_s < 3.0 for m in faults)
    m = Mutator(vocab, random.Random(1))
    child = m.mutate(draws[0][0], draws[0][1])
    assert 1 <= len(child) <= 8 and all(c.checked() == c for c in child)


def test_ddmin_keeps_the_faults_that_fail_together():
    faults = tuple(Mutation(FaultKind.BROWNOUT, (("id", i), ("at_s", 1.0 + i / 100)))
                   for i in range(1, 9))
    culprits = {faults[2], faults[6]}

    def run(inputs):
        return [Execution(("x",) if culprits <= set(i) else (), (), frozenset(), 0.0)
                for i in inputs]

    shrunk, used = campaign.shrink(faults, ("x",), run)
    assert set(shrunk) == culprits and used < campaign.SHRINK_RUNS


SMALL = dict(expect=str(CASE), runs=32, seed=3,       # the default guidance: lines, packets
             kinds=tuple(k for k in DEFAULT_KINDS if k.value.startswith("status_")))


def test_the_planted_bug_is_found_shrunk_and_replayed_and_ours_survives(tmp_path):
    report = campaign.fuzz(campaign.Settings(**SMALL, main_file=str(PLANTED),
                                             out=str(tmp_path)))
    assert report.findings and all(f.failures == ("expect: no firmware exception",)
                                   for f in report.findings)
    f = report.findings[0]
    assert report.executions <= 2000 and 1 <= len(f.shrunk) <= 3
    assert any(m.kind is FaultKind.STATUS_WRONG_ID for m in f.shrunk)
    assert f.replayed and Path(f.trace).stat().st_size > 0
    r = hexhil_in_process("test", f.expect, "--in-process", PLANTED)
    assert r.returncode == 1 and "no firmware exception" in r.stdout and "FAIL" in r.stdout
    ours = campaign.fuzz(campaign.Settings(**SMALL))
    assert ours.findings == [] and ours.executions == report.executions


def test_a_campaign_is_its_seed_on_one_server_on_two_and_on_dask():
    import distributed
    settings = campaign.Settings(**{**SMALL, "runs": 14}, main_file=str(PLANTED),
                                 shrink=False)
    one, two = campaign.fuzz(settings), campaign.fuzz(replace(settings, jobs=2))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        dask = campaign.fuzz(replace(settings, jobs=2, scheduler=cluster.scheduler_address))
    for other in (two, dask):
        assert other.as_dict()["findings"] == one.as_dict()["findings"]
        assert (other.executions, other.features, other.corpus) == (
            one.executions, one.features, one.corpus)
    assert one.findings and one.features > one.baseline_features   # found at the 12th


def test_bad_settings_are_one_line_errors():
    r = hexhil_in_process("fuzz", "scenarios/flat-tripod.toml", "--expect", CASE, "--window", "5")
    assert r.returncode == 2 and "--window" in r.stderr and "Traceback" not in r.stderr
    r = hexhil_in_process("fuzz", "scenarios/flat-tripod.toml", "--expect", CASE,
                          "--kinds", "status_nonsense")
    assert r.returncode == 2 and "--kinds" in r.stderr and "status_nonsense" in r.stderr


def test_the_example_case_on_the_command_line_with_json(tmp_path):
    import resource

    def cpu_s() -> float:
        u = resource.getrusage(resource.RUSAGE_CHILDREN)
        return u.ru_utime + u.ru_stime

    before = cpu_s()
    r = hexhil("fuzz", "scenarios/flat-tripod.toml", "--expect",
               "examples/fuzz-flat-tripod.toml", "--runs", "3", "--seed", "2",
               "--kinds", "status_twin", "--json", "--quiet")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout.splitlines()[-1])
    assert report["executions"] == 3 and report["findings"] == []
    assert report["features"] >= report["baseline_features"] > 0
    assert 0 < report["child_cpu_s"] < cpu_s() - before     # the forked children's, of all


def test_the_packet_sequence_passes_a_direction_mistake_on_or_drops_it():
    from hexhil.hil.servobus.master_check import MasterCheck
    from hexhil.bus_fuzz.features import PacketSequence

    alone = PacketSequence(None)
    alone.direction_mistake(5, "tx_while_receiving", "no master check")
    alone.master_bytes(None, 0, dxl.read(1, 36, 6) + dxl.read(2, 36, 6) + dxl.read(1, 36, 6))
    assert len(alone.pairs) == 3          # (start, 1), (1, 2), (2, 1)
    two = PacketSequence(None)
    two.master_bytes(None, 0, dx2.read(1, 132, 4) + dx2.read(2, 132, 4) + dx2.read(1, 132, 4))
    assert len(two.pairs) == 3 and two._last == (dx2.READ, 1)     # Protocol 2.0's packets
    check = MasterCheck()
    PacketSequence(check).direction_mistake(5, "tx_while_receiving", "pin low")
    assert check.counts["tx_while_receiving"] == 1


def test_the_held_trace_judges_as_the_written_file_does(tmp_path):
    """The fork server's trace in memory (boot decoded at the fork, the rest at the end)
    holds what the file would, on every topic the expectations read."""
    from hexhil.bus_fuzz.execution import Target, run_input
    from hexhil.bus_fuzz.held_trace import HeldTrace
    from hexhil.expect import spec, verdicts

    case = replace(spec.load(ROOT / "examples" / "fuzz-flat-tripod.toml"), duration_s=0.7)
    target = Target(case, 0.5, coverage=False)
    held: list[HeldTrace] = []
    caps: list[float] = []

    def setup(run):
        write = run.recorder._write_chunk
        held.append(HeldTrace(run, case))
        caps.append(run.limits.wall_s(case.duration_s))
        keep = run.recorder._write_chunk
        run.recorder._write_chunk = lambda msgs, packing=None: (keep(msgs), write(msgs))

    def wrap(run, exchange):
        def hooked(data, closed):
            if not held[0].boot and run.sim.clock.t_us >= 400_000:
                held[0].at_fork()
            return exchange(data, closed)
        return hooked

    trace = tmp_path / "run.mcap"
    cpus = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cpus)})      # as the server: the recorder encodes here
    try:
        summary = run_input(target, (), trace, wrap=wrap, setup=setup)
    finally:
        os.sched_setaffinity(0, cpus)
    assert caps == [float("inf")]         # no wall-clock cap: the server waits for inputs
    rec = held[0].recording(summary)
    assert held[0].boot and rec.messages[verdicts.topics.T_BODY][-1][0] > 0.6
    assert rec.messages == verdicts.read(trace, summary, verdicts.topics_read(case)).messages
    untimed = lambda outcomes: [replace(o, time_s=0.0) for o in outcomes]
    assert untimed(verdicts.judged(case, rec)) == untimed(verdicts.evaluate(case, summary, trace))


def test_a_swing_press_presses_once_a_swing_after_the_foot_is_lifted():
    entry = FaultEntry.parse(FaultKind.SWITCH_SWING_PRESS,
                             {"leg": "LM", "after_s": 0.05, "press_s": 0.02, "at_s": 0.0}, "t")
    f = Faults(FaultsConfig(switch_swing_press=(entry,)))
    f.start(VirtualClock(), 0)
    f.apply_due(0)
    feet = [True] * 6
    seen = []
    for t_ms in range(0, 400, 10):
        feet[1] = not 100 <= t_ms < 300           # LM in the air from 100 ms to 300 ms
        seen.append(f.switch_bits(t_ms * 1000, 0, lambda: feet))
    pressed = [t for t, bits in zip(range(0, 400, 10), seen) if bits]
    assert pressed == [150, 160] and set(seen) == {0, 2}    # bit 1: LM, one press, 20 ms
    assert [n for _, n, _ in f.log] == ["switch_swing_press", "swing_press"]
    assert f.switch_bits(500_000, 0) == 0                   # no world, no swing


def test_a_swing_press_lands_in_the_swing_of_a_walking_run(tmp_path):
    """On flat-tripod the press comes while the leg's foot carries no load (the world's
    ground truth), and the firmware reads it as a contact."""
    from hexhil.expect import case_runs
    from hexhil.hil import scenario as scenario_mod

    sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml").overlay(
        {"faults": {"switch_swing_press": [{"leg": 0, "at_s": 0.3, "after_s": 0.2}]}})
    at_press: list[tuple[int, bool]] = []

    def setup(run):
        report, world = run.sim.faults.report, run.sim.world

        def heard(t_us, name, detail):
            if name == "swing_press":
                at_press.append((t_us, world.foot_contacts()[0]))
            report(t_us, name, detail)
        run.sim.faults.report = heard

    summary, result = case_runs.run_scenario(sc, 1, 2.0, "cpython-inprocess", None,
                                             tmp_path / "run.mcap", setup=setup,
                                             master_check=False)
    assert at_press and not any(loaded for _, loaded in at_press)
    assert all(t >= 500_000 for t, _ in at_press)
    assert summary["switch_edges"] == 2 * len(at_press), (summary["switch_edges"], at_press)
