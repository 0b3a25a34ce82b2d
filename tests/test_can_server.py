"""Live CAN for stock tools: python-can's own socketcand client attached to a running
lockstep simulation receives every frame of the run, and frames it sends reach the
firmware side of the bus."""
from __future__ import annotations

import threading
import time

import can
import pytest

from hexhil.hil.canbus.socketcand import CanServer, frame_line, parse_send
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil import scenario
from hexhil.trace import protobuf as pb
from hexhil.trace import recorder as rec
from hexhil.trace import topics
from hexhil.trace.reader import open_trace
from hexhil.protocol import can_frames


def test_wire_format_matches_the_stock_client_parser():
    from can.interfaces.socketcand.socketcand import (convert_ascii_message_to_can_message,
                                                      convert_can_message_to_ascii_message)

    m = convert_ascii_message_to_can_message(
        frame_line(12_345_678, 0x120, b"\x01\xab\x00").decode())
    assert (m.arbitration_id, bytes(m.data), m.timestamp, m.is_extended_id) == \
           (0x120, b"\x01\xab\x00", 12.345678, False)
    m = convert_ascii_message_to_can_message(frame_line(5, 0x1ABCDEF, b"", True).decode())
    assert (m.arbitration_id, bytes(m.data), m.is_extended_id) == (0x1ABCDEF, b"", True)
    line = convert_can_message_to_ascii_message(
        can.Message(arbitration_id=0x200, data=b"\x01\x00\x0f", is_extended_id=False))
    assert parse_send(line[2:-2]) == (0x200, b"\x01\x00\x0f", False)
    with pytest.raises(ValueError):
        parse_send("send 200 3 01 02")


def test_wrong_channel_is_refused():
    with CanServer(port=0) as srv:
        with pytest.raises(can.CanError):
            can.Bus(interface="socketcand", channel="can7", host="127.0.0.1", port=srv.port)


def test_stock_client_receives_every_frame_of_a_live_run(tmp_path):
    srv = CanServer(port=0)
    clients = [can.Bus(interface="socketcand", channel="hexhil0", host="127.0.0.1",
                       port=srv.port) for _ in range(2)]
    assert srv.wait_for_clients(2, timeout_s=10)
    received: list[list[can.Message]] = [[], []]
    stop = threading.Event()

    def listen(k: int) -> None:
        while not stop.is_set() or len(received[k]) < srv.frames_published:
            m = clients[k].recv(timeout=0.5)
            if m is None and stop.is_set():
                return
            if m is not None:
                received[k].append(m)

    threads = [threading.Thread(target=listen, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    # a stock tool commanding the robot: gait stop, sent before the run starts
    arb, data = can_frames.encode("gait_command", command=0, gait=0, step_length_m=0.05,
                                  step_height_m=0.03, period_s=2.0)
    clients[0].send(can.Message(arbitration_id=arb, data=data, is_extended_id=False))
    trace = tmp_path / "live.mcap"
    s = {section: {} for section in scenario.SCHEMA}
    try:
        with rec.Recorder(trace, {"seed": 0}) as r:
            deadline = time.monotonic() + 5
            while srv.frames_received < 1 and time.monotonic() < deadline:
                time.sleep(0.01)
            result = Simulator(s, seed=0, recorder=r, can_server=srv).run(
                duration_s=2.0, python="micropython")
        srv.close()  # drains every queued frame first
    finally:
        stop.set()
        for t in threads:
            t.join(timeout=10)
        for c in clients:
            c.shutdown()
    assert result.exit_code == 0
    with open_trace(trace) as tr:
        frames = [(m.log_time_ns, pb.CanFrame.FromString(m.data))
                  for m in tr.messages([topics.T_CAN_RAW])]
    sent = [(t, f) for t, f in frames if f.direction == "tx"]
    assert len(sent) >= 30 and srv.frames_published == len(sent)
    want = [(f.arbitration_id, f.data, round(t / 1e9, 6)) for t, f in sent]
    for k in range(2):
        got = [(m.arbitration_id, bytes(m.data), round(m.timestamp, 6)) for m in received[k]]
        assert got == want  # every frame, in order, with virtual timestamps
    # the client's frame reached the firmware's side of the bus, and the trace
    assert any(f.direction == "rx" and f.arbitration_id == arb and f.data == data
               for _, f in frames)
