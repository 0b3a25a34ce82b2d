"""The Recorder: files the stock mcap reader opens, valid schemas, Foxglove names,
log-time order, decoded packets and frames, determinism and SIGKILL safety."""
from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Chunk, MessageIndex
from mcap.stream_reader import StreamReader
from mcap_protobuf.decoder import DecoderFactory

from hexhil.trace import protobuf as pb
from hexhil.trace import reader as trace_reader
from hexhil.trace import recorder as rec
from hexhil.trace import recover as trace_recover
from hexhil.trace.target import partial_of
from hexhil.trace.writer import software_version
from hexhil.trace import topics
from hexhil.protocol import can_frames
from hexhil.protocol.dynamixel import v1 as dynamixel
from conftest import HEXHIL, ROOT


def _record(path: Path, cycles: int = 400, idle_budgets: list[int] | None = None,
            encode_in: rec.EncodeIn = rec.EncodeIn.CHILD_PROCESS) -> dict:
    """A synthetic run touching every recorder method; returns what was sent. With
    ``idle_budgets``, each cycle ends with ``idle()`` given the next budget in turn."""
    sent = {"tx": [], "rx": [], "can": [], "link": []}
    r = rec.Recorder(path, {"scenario": "scenarios/x.toml", "seed": 7, "cmd": ["run"]},
                     encode_in=encode_in)
    for i in range(cycles):
        t = i * 10_000
        pkt = dynamixel.read(1 + i % 18, 36, 2)
        st = dynamixel.status(1 + i % 18, dynamixel.ERR_OVERLOAD if i == 5 else 0,
                              bytes((i & 0xFF, 2)))
        # bytes split at arbitrary points, as a UART delivers them
        r.serial(t, "tx", pkt[:3])
        r.serial(t + 10, "tx", pkt[3:])
        r.serial(t + 600, "rx", b"\x00" + st)  # a garbage byte before the status
        sent["tx"].append(pkt)
        sent["rx"].append(st)
        arb, data = can_frames.encode("heartbeat", state=2, fault_flags=0, cycle=i, overruns=0)
        r.can(t + 700, arb, data)
        sent["can"].append((arb, data))
        # telemetry reported slightly late (older than the last message): still in order
        r.telemetry(t + 650, {"cycle": i, "state": "walking"})
        if i % 50 == 0:
            r.switch_edge(t, i // 50 % 6, True)
            r.servo_state(t, [{"id": k, "position_rad": 0.01 * k, "load_frac": -0.1}
                              for k in range(1, 19)])
            r.body_pose(t, (0.001 * i, 0.0, 0.12), (1.0, 0.0, 0.0, 0.0))
            r.joints(t, ["coxa_LF", "femur_LF"], [0.1, -0.2], [0.0, 0.5], [0.01, 0.02])
            r.fault(t, "unplug", "servo 3 unplugged")
            r.link(t, b"S\x08\x00" + bytes(8), b"\x0b\x00" + bytes(11))
            sent["link"].append((t, b"S\x08\x00" + bytes(8), b"\x0b\x00" + bytes(11)))
        if idle_budgets:
            r.idle(idle_budgets[i % len(idle_budgets)])
    r.close()
    return sent


def test_stock_reader_schemas_and_foxglove_names(tmp_path):
    path = tmp_path / "run.mcap"
    sent = _record(path)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        names = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert names[topics.T_BODY] == "foxglove.FrameTransform"
        assert names[topics.T_JOINTS] == "foxglove.JointStates"
        assert names[topics.T_FAULTS] == "foxglove.Log"
        assert names["/can/heartbeat"] == "hexhil.can.heartbeat"
        assert {ci.compression for ci in summary.chunk_indexes} == {"zstd"}
        # 4 s of virtual time in 0.5 s windows: several chunks, not one at the end
        assert summary.statistics.chunk_count >= 8
        meta = {m.name: m.metadata for m in reader.iter_metadata()}["hexhil"]
        assert meta["seed"] == "7" and meta["scenario"] == "scenarios/x.toml"
        assert meta["software_version"] == software_version()
        # every protobuf message decodes with the schema stored in the file
        packets = {"tx": [], "rx": []}
        bursts = {"tx": b"", "rx": b""}
        links = []
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=[topics.T_SERIAL, topics.T_JOINTS, topics.T_BODY, topics.T_LINK]):
            if channel.topic == topics.T_SERIAL:
                bursts[decoded.direction] += decoded.data
                assert decoded.length == len(decoded.data)
                assert all(p.direction == decoded.direction for p in decoded.packets)
                packets[decoded.direction] += decoded.packets
            elif channel.topic == topics.T_LINK:
                links += [(x.t_us, x.request, x.reply) for x in decoded.exchanges]
            elif channel.topic == topics.T_JOINTS:
                assert [j.name for j in decoded.joints] == ["coxa_LF", "femur_LF"]
                assert decoded.joints[1].velocity == 0.5
            else:
                assert decoded.translation.z == 0.12 and decoded.rotation.w == 1.0
    assert [p.raw for p in packets["tx"]] == sent["tx"]
    assert [p.raw for p in packets["rx"]] == sent["rx"]
    # every raw byte is there too, the garbage before each status included
    assert bursts["tx"] == b"".join(sent["tx"])
    assert bursts["rx"] == b"".join(b"\x00" + s for s in sent["rx"])
    assert links == sent["link"]
    assert packets["tx"][0].instruction == "READ"
    assert packets["rx"][5].errors == "overload"
    # jsonschema channels: the schema parses and every decoded key is declared in it
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema in summary.schemas.values():
            if schema.encoding == "jsonschema":
                assert json.loads(schema.data)["type"] == "object"
        props = json.loads(next(s for s in summary.schemas.values()
                                if s.name == "hexhil.can.heartbeat").data)["properties"]
        got = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=["/can/heartbeat"])]
    assert len(got) == len(sent["can"])
    for values, (arb, data) in zip(got, sent["can"]):
        assert set(values) <= set(props)
        name, want = can_frames.decode(arb, data)
        assert name == "heartbeat"
        assert all(values[k] == want[k] for k in want)


def test_messages_are_in_log_time_order_in_the_file(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, cycles=200)
    with open(path, "rb") as f:
        times = [m.log_time for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    assert times == sorted(times)
    assert len(times) > 1000


@settings(max_examples=300, deadline=None)
@given(direction=st.sampled_from(["tx", "rx", ""]), servo_id=st.integers(0, 254),
       code=st.integers(0, 255), params=st.binary(max_size=300), raw=st.binary(max_size=300),
       kind=st.text(max_size=5), t_us=st.integers(0, 2**64 - 1))
def test_hand_encoded_protobuf_is_what_the_generated_classes_write(direction, servo_id, code,
                                                                   params, raw, kind, t_us):
    links = [(kind, params, raw, t_us), ("", b"", b"", 0), (kind, raw, params, servo_id)]
    assert b"".join(pb.encode_link_exchange(*x) for x in links) == pb.LinkExchanges(exchanges=[
        pb.LinkExchange(kind=k, request=q, reply=p, t_us=t) for k, q, p, t in links
    ]).SerializeToString()
    if direction == "rx":
        names = ("", ",".join(dynamixel.error_names(code)))
    else:
        names = (dynamixel.INSTRUCTION_NAMES.get(code, "0x%02X" % code), "")
    assert pb.encode_dynamixel_packet(direction, servo_id, code, params, raw) == \
        pb.DynamixelPacket(direction=direction, id=servo_id, code=code, instruction=names[0],
                            errors=names[1], params=params, raw=raw).SerializeToString()
    packet = pb.DynamixelPacket(direction=direction, id=servo_id, code=code, params=params,
                                 raw=raw)
    for packets in ([], [packet], [packet, packet]):
        encoded = [p.SerializeToString() for p in packets]
        assert pb.encode_serial_bytes(direction, raw, encoded) == pb.SerialBytes(
            direction=direction, data=raw, length=len(raw), packets=packets
        ).SerializeToString()


finite_or_not = st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=200, deadline=None)
@given(t_ns=st.integers(0, 10**15), parent=st.text(max_size=8), child=st.text(max_size=8),
       pos=st.tuples(finite_or_not, finite_or_not, st.sampled_from([0.0, -0.0, 0.12])),
       quat=st.tuples(finite_or_not, finite_or_not, finite_or_not, st.just(0.0)),
       joints=st.lists(st.tuples(st.text(max_size=6), finite_or_not, finite_or_not,
                                 st.sampled_from([0.0, -0.0, 1.5])), max_size=5),
       servos=st.lists(st.fixed_dictionaries(
           {"id": st.integers(0, 253), "position_rad": finite_or_not,
            "velocity_rad_s": finite_or_not, "load_frac": finite_or_not,
            "temperature_c": finite_or_not, "torque_enabled": st.booleans(),
            "error": st.integers(0, 255)},
           optional={"moving": st.booleans(), "voltage_v": finite_or_not}), max_size=4),
       can=st.tuples(st.sampled_from(["tx", "rx"]), st.integers(0, 0x1FFFFFFF), st.booleans(),
                     st.binary(max_size=8), st.text(max_size=10)))
def test_hand_encoded_ground_truth_and_can_are_what_the_generated_classes_write(
        t_ns, parent, child, pos, quat, joints, servos, can):
    ft = pb.FrameTransform(parent_frame_id=parent, child_frame_id=child)
    ft.timestamp.FromNanoseconds(t_ns)
    ft.translation.x, ft.translation.y, ft.translation.z = pos
    ft.rotation.w, ft.rotation.x, ft.rotation.y, ft.rotation.z = quat
    assert pb.encode_frame_transform(t_ns, parent, child, pos, quat) == ft.SerializeToString()
    js = pb.JointStates()
    js.timestamp.FromNanoseconds(t_ns)
    for name, p, v, e in joints:
        j = js.joints.add()
        j.name, j.position, j.velocity, j.effort = name, p, v, e
    assert pb.encode_joint_states(t_ns, *([j[k] for j in joints] for k in range(4))) == \
        js.SerializeToString()
    assert pb.encode_servo_states(servos) == pb.ServoStates(
        servos=[pb.ServoState(**s) for s in servos]).SerializeToString()
    direction, arb, ext, data, name = can
    assert pb.encode_can_frame(direction, arb, ext, data, name) == pb.CanFrame(
        direction=direction, arbitration_id=arb, is_extended_id=ext, dlc=len(data), data=data,
        name=name).SerializeToString()


def test_can_signals_in_the_trace_are_the_dbc_decoding(tmp_path):
    """The recorder decodes our frames with protocol/can_frames.py: the same numbers
    cantools gets from protocol/hexhil.dbc."""
    import cantools

    db = cantools.database.load_file(str(ROOT / "protocol" / "hexhil.dbc"))
    frames = [can_frames.encode("heartbeat", state=2, fault_flags=5, cycle=1234, overruns=3),
              can_frames.encode("force", fx_n=0.1234, fy_n=-0.5, fz_n=1.75, sample=77),
              can_frames.encode("tactile", switches=0b100101, overcoming=2, step_counter=9)]
    with rec.Recorder(tmp_path / "c.mcap", {}) as r:
        for i, (arb, data) in enumerate(frames):
            r.can(i * 1000, arb, data)
    with open(tmp_path / "c.mcap", "rb") as f:
        got = [json.loads(m.data) for _, c, m in make_reader(f).iter_messages()
               if c.topic.startswith("/can/") and c.topic != topics.T_CAN_RAW]
    assert len(got) == len(frames)
    for values, (arb, data) in zip(got, frames):
        want = db.get_message_by_frame_id(arb).decode(data, decode_choices=False)
        assert values.pop("direction") == "tx"
        assert values.keys() == want.keys()
        assert all(values[k] == pytest.approx(want[k], abs=1e-12) for k in want)


def test_message_indexes_point_at_their_messages(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, cycles=120)
    checked = 0
    with open(path, "rb") as f:
        chunk = None
        for record in StreamReader(f, emit_chunks=True).records:
            if isinstance(record, Chunk):
                chunk = zstandard.ZstdDecompressor().decompress(
                    record.data, max_output_size=record.uncompressed_size)
            elif isinstance(record, MessageIndex):
                for log_time, offset in record.records:
                    opcode, _, channel, _, log_t = struct.unpack_from("<BQHIQ", chunk, offset)
                    assert (opcode, channel, log_t) == (Opcode.MESSAGE, record.channel_id,
                                                        log_time)
                    checked += 1
    with open(path, "rb") as f:
        assert checked == make_reader(f).get_summary().statistics.message_count > 700


def test_same_run_same_bytes(tmp_path):
    _record(tmp_path / "a.mcap", cycles=120)
    _record(tmp_path / "b.mcap", cycles=120)
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()


@settings(max_examples=15, deadline=None)
@given(budgets=st.lists(st.integers(0, 40), min_size=1, max_size=8))
def test_idle_work_changes_no_byte(tmp_path_factory, budgets):
    """Whatever the simulator hands to idle(), and when, the file is the same, and the
    same as a child process encoding it writes."""
    tmp = tmp_path_factory.mktemp("idle")
    _record(tmp / "plain.mcap", cycles=120)
    _record(tmp / "idle.mcap", cycles=120, idle_budgets=budgets,
            encode_in=rec.EncodeIn.THIS_PROCESS)
    assert (tmp / "idle.mcap").read_bytes() == (tmp / "plain.mcap").read_bytes()


def test_a_recorded_run_is_the_same_bytes_however_it_is_scheduled(tmp_path):
    """How much encoding overlaps the firmware depends on timing (the simulator skips
    idle work when the firmware has already answered); the trace must not."""
    from hexhil.run_summary import run

    run("scenarios/flat-tripod.toml", 2.0, out=str(tmp_path / "free.mcap"))
    cores = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cores)})  # the firmware child inherits it
    try:
        run("scenarios/flat-tripod.toml", 2.0, out=str(tmp_path / "one.mcap"))
    finally:
        os.sched_setaffinity(0, cores)
    assert (tmp_path / "one.mcap").read_bytes() == (tmp_path / "free.mcap").read_bytes()


def test_unwritable_path_is_a_user_error(tmp_path):
    from hexhil.protocol.errors import UserError

    with pytest.raises(UserError, match="cannot write trace"):
        rec.Recorder(tmp_path / "no" / "such" / "dir.mcap")
    assert rec.open_recorder(None) is None


def test_a_packet_hidden_behind_a_bad_header_is_decoded_at_close(tmp_path):
    """A garbage header whose LEN runs past the end of the capture hides a valid packet;
    close() rescans and logs it on a /serial message of no new bytes."""
    path = tmp_path / "hidden.mcap"
    pkt = dynamixel.read(3, 36, 2)
    with rec.Recorder(path) as r:
        r.serial(1000, "tx", b"\xff\xff\x05\x40" + pkt)
    with trace_reader.open_trace(path) as tr:
        got = [(m.log_time_ns, v["data"], [p["raw"] for p in v["packets"]])
               for m, v in tr.decoded([topics.T_SERIAL])]
    assert got == [(1_000_000, (b"\xff\xff\x05\x40" + pkt).hex(), []),
                   (1_000_000, "", [pkt.hex()])]


KILL_SCRIPT = textwrap.dedent("""
    import sys, time
    from hexhil.trace.recorder import Recorder
    r = Recorder(sys.argv[1], {"seed": 1})
    budget = int(sys.argv[2])        # -1: never idle(), like a world without firmware
    t = 0
    while True:                      # 1 kHz of messages, for ever
        r.serial(t, "tx", b"\\xff\\xff\\x01\\x04\\x02\\x24\\x02\\xd2")
        r.telemetry(t, {"t_us": t})
        if budget >= 0:
            r.idle(budget)
        if t == 3_700_000:           # 3.7 simulated seconds in: tell the parent
            print("ready", flush=True)
            time.sleep(60)
        t += 1000
""")


@pytest.mark.parametrize("idle_budget", [-1, 0, 3])
def test_sigkill_loses_at_most_the_last_simulated_second(tmp_path, idle_budget):
    script = tmp_path / "writer.py"
    script.write_text(KILL_SCRIPT)
    path = tmp_path / "killed.mcap"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, str(script), str(path), str(idle_budget)],
                            stdout=subprocess.PIPE,
                            env=env, cwd=ROOT, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    # the killed file is unreadable to the seeking reader (no summary) ...
    from hexhil.protocol.errors import UserError
    with pytest.raises(UserError, match="recover"):
        trace_reader.info(path)
    # ... and recover salvages everything but the last window
    out = tmp_path / "recovered.mcap"
    r = trace_recover.recover(path, out)
    assert not r["complete"]
    assert 3.7 - 1.0 <= r["end_s"] <= 3.7
    info = trace_reader.info(out)
    counts = {t["topic"]: t["messages"] for t in info["topics"]}
    # no gaps: every millisecond up to the last recovered one is there, on both topics
    n = int(round(r["end_s"] * 1000)) + 1
    assert counts == {topics.T_SERIAL: n, topics.T_TELEMETRY: n}
    with trace_reader.open_trace(out) as tr:
        ts = [v["t_us"] for _, v in tr.decoded([topics.T_TELEMETRY])]
    assert ts == list(range(0, n * 1000, 1000))


def test_sigkilled_hexhil_run_recovers_to_an_exact_prefix(tmp_path):
    """A real `hexhil run --out` killed mid-run: recover gives back a trace whose messages
    are exactly the first part of the same run recorded to the end (runs are
    deterministic), up to the last chunk written before the kill."""
    import time

    full = tmp_path / "full.mcap"
    subprocess.run([*HEXHIL, "run", "scenarios/flat-tripod.toml", "--duration", "4",
                    "--out", str(full)], cwd=ROOT, check=True, capture_output=True)
    killed = tmp_path / "killed.mcap"
    proc = subprocess.Popen([*HEXHIL, "run", "scenarios/flat-tripod.toml", "--duration", "600",
                             "--out", str(killed)], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    # wait until the file holds more than the first 4 simulated seconds' worth of chunks
    while time.monotonic() < deadline and proc.poll() is None:
        partial = partial_of(killed)   # what a run writes until it renames it at the end
        if partial.exists() and partial.stat().st_size > full.stat().st_size:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    r = trace_recover.recover(killed, tmp_path / "rec.mcap")
    assert not r["complete"] and r["end_s"] >= 3.0
    with trace_reader.open_trace(full) as a, trace_reader.open_trace(tmp_path / "rec.mcap") as b:
        want = [(m.topic, m.log_time_ns, m.data) for m in a.messages(end_s=3.0)]
        got = [(m.topic, m.log_time_ns, m.data) for m in b.messages(end_s=3.0)]
    assert got == want and len(want) > 1000

