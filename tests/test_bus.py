"""The lockstep half-duplex bus: wire time, return delay, collisions, echo, baud, faults."""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.wire import resample
from hexhil.hil.clock import VirtualClock
from hexhil.hil.scenario import FaultEntry, FaultKind
from hexhil.hil.servobus.faults import Faults
from hexhil.cli.bus import parse_flag
from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.hil.servobus.servo_layout import OVERLOAD_TIME_US
from hexhil.hil import scenario
from hexhil.protocol.errors import UserError
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl


def make_bus(n: int = 18, **kw) -> Bus:
    return Bus([Servo(i) for i in range(1, n + 1)], VirtualClock(), **kw)


def transact(bus: Bus, pkt: bytes, n: int, timeout_us: int = 5000) -> list[dxl.Packet]:
    bus.master_write(pkt)
    return dxl.Parser().feed(bus.master_read(n, timeout_us))


def test_read_of_two_bytes_costs_80_plus_500_plus_80_us():
    bus = make_bus()
    assert bus.servo(3).value("return_delay_time") == 250
    bus.master_write(dxl.read(3, ax12.PRESENT_POSITION, 2))
    assert bus.clock.t_us == 80
    reply = bus.master_read(8, 10_000)
    assert bus.clock.t_us == 80 + 500 + 80
    assert reply == dxl.status(3, 0, bytes((0, 2)))


def test_return_delay_zero_and_a_slower_line():
    bus = make_bus(2, baud=57142)
    for s in bus.servos:
        s.table[ax12.BAUD_RATE] = 34  # 2 000 000 / 35 = 57142 bps
        s.table[ax12.RETURN_DELAY_TIME] = 0
    bus._reindex()
    (pkt,) = transact(bus, dxl.ping(2), 6)
    assert pkt.id == 2 and bus.clock.t_us == (6 * 10_000_000) // 57142 * 2  # 1050 + 1050


def test_missing_id_waits_out_the_timeout():
    bus = make_bus()
    bus.master_write(dxl.ping(30))
    assert bus.master_read(6, 2000) == b"" and bus.clock.t_us == 60 + 2000


def test_sync_write_reaches_all_servos_without_reply():
    bus = make_bus()
    entries = [(i, (600 + i).to_bytes(2, "little") + (200).to_bytes(2, "little"))
               for i in range(1, 19)]
    pkt = dxl.sync_write(ax12.GOAL_POSITION, 4, entries)
    assert len(pkt) == 98
    bus.master_write(pkt)
    assert bus.clock.t_us == 980 and bus.master_read(1, 3000) == b""
    assert [s.value("goal_position") for s in bus.servos] == [600 + i for i in range(1, 19)]


def test_master_talking_over_a_reply_corrupts_both():
    bus = make_bus()
    before = [s.value("goal_position") for s in bus.servos]
    bus.master_write(dxl.read(1, ax12.PRESENT_POSITION, 2))  # reply due at 580..660
    entries = [(i, b"\x00\x03\x10\x00") for i in range(1, 19)]
    bus.master_write(dxl.sync_write(ax12.GOAL_POSITION, 4, entries))  # 80..1060
    heard = bus.master_read(8, 2000)
    assert bus.stats["collisions"] == 1
    assert dxl.Parser().feed(heard) == []  # the status packet is ruined...
    assert [s.value("goal_position") for s in bus.servos] == before  # ...and so is the write


def test_two_servos_answering_at_once_collide():
    a, b = Servo(5), Servo(5)
    a.table[ax12.RETURN_DELAY_TIME] = 0
    b.table[ax12.RETURN_DELAY_TIME] = 10  # 20 us later: two bytes of overlap offset
    bus = Bus([a, b], VirtualClock())
    bus.master_write(dxl.read(5, 0, 4))
    heard = bus.master_read(64, 1000)
    assert bus.stats["collisions"] == 1 and dxl.Parser().feed(heard) == []


def test_echo_puts_the_masters_bytes_before_the_reply():
    bus = make_bus(echo=True)
    bus.master_write(dxl.ping(4))
    heard = bus.master_read(12, 2000)
    assert heard == dxl.ping(4) + dxl.status(4)
    first = dxl.Parser().feed(heard)[0]
    # a client that does not strip echo takes its own PING for a status with error bit 0
    assert (first.id, first.code) == (4, dxl.PING) and dxl.error_names(first.code) == ["input_voltage"]


def test_servo_at_another_baud_sees_garbage():
    s = Servo(1)
    s.table[ax12.BAUD_RATE] = 34  # 57142 bps on a 1 Mbps line
    bus = Bus([s], VirtualClock())
    bus.master_write(dxl.ping(1))
    assert dxl.Parser().feed(bus.master_read(64, 5000)) == []
    assert s.instructions == 0
    garbled = resample(dxl.ping(1), 1_000_000, 57142)
    assert garbled != dxl.ping(1) and len(garbled) < 6


def test_uart_resampling_tolerates_small_mismatch_only():
    data = bytes(range(256))
    assert resample(data, 1_000_000, 1_000_000) == data
    assert resample(data, 1_000_000, 1_020_000) == data   # 2 %: a UART copes
    assert resample(data, 1_000_000, 1_111_111) != data   # 11 %: it does not


def test_bad_checksum_is_answered_with_bit_4_and_garbage_is_skipped():
    bus = make_bus()
    bad = bytearray(dxl.ping(2))
    bad[-1] ^= 0x5A
    (pkt,) = transact(bus, bytes(bad), 6)
    assert (pkt.id, pkt.code) == (2, dxl.ERR_CHECKSUM)
    bus.master_write(b"\x00\xff\x13\x37\xff")
    (pkt,) = transact(bus, dxl.ping(2), 6)
    assert (pkt.id, pkt.code) == (2, 0)


def test_hooks_see_every_burst_and_time_only_moves_forward():
    seen, times = [], []
    bus = make_bus(on_bytes=lambda t, d, b: seen.append((t, d, b)), advance=times.append)
    transact(bus, dxl.read(1, 36, 2), 8)
    transact(bus, dxl.ping(9), 6)
    assert seen == [(0, "tx", dxl.read(1, 36, 2)), (580, "rx", dxl.status(1, 0, b"\x00\x02")),
                    (660, "tx", dxl.ping(9)), (660 + 60 + 500, "rx", dxl.status(9))]
    assert times == sorted(times) and times[-1] == bus.clock.t_us == 660 + 60 + 500 + 60


# --- faults -------------------------------------------------------------------------
def faults_of(seed: int = 0, **section) -> Faults:
    """The faults of a scenario whose ``[faults]`` is ``section``."""
    return Faults(scenario.parse({"faults": section}).faults, seed)


def run_with_faults(seed: int, **kw) -> tuple[list, bytes]:
    faults = faults_of(seed, **kw)
    bus = make_bus(faults=faults)
    heard = bytearray()
    for k in range(200):
        bus.master_write(dxl.read(1 + k % 18, 36, 2))
        heard += bus.master_read(8, 1000)
    return faults.log, bytes(heard)


def test_line_faults_are_seeded_and_reported():
    a = run_with_faults(7, bit_error_rate=1e-3, drop_status_rate=0.05)
    assert a == run_with_faults(7, bit_error_rate=1e-3, drop_status_rate=0.05)
    assert a != run_with_faults(8, bit_error_rate=1e-3, drop_status_rate=0.05)
    names = [n for _, n, _ in a[0]]
    bits = 200 * 16 * 8
    assert 0.5 * bits * 1e-3 < names.count("bit_error") < 1.5 * bits * 1e-3
    assert 2 <= names.count("drop_status") <= 25
    assert len(a[1]) < 200 * 8


def test_unplugged_servo_is_silent_then_returns_power_cycled():
    faults = faults_of(unplug=[{"id": 4, "at_s": 0.01, "until_s": 0.02}])
    bus = make_bus(faults=faults)
    transact(bus, dxl.write(4, ax12.TORQUE_ENABLE, b"\x01"), 6)
    assert len(transact(bus, dxl.ping(4), 6)) == 1
    bus.idle_until(15_000)
    assert transact(bus, dxl.ping(4), 6) == []
    bus.idle_until(25_000)
    assert len(transact(bus, dxl.ping(4), 6)) == 1
    assert bus.servo(4).value("torque_enable") == 0
    assert [(t, n) for t, n, _ in faults.log] == [(10_000, "unplug"), (20_000, "unplug_end")]


def test_stall_overheat_and_sag_show_in_status_packets():
    faults = faults_of(stall=[{"id": 1, "at_s": 0.0}],
                       overheat=[{"id": 2, "at_s": 0.0, "temperature_c": 95.0}],
                       voltage_sag=[{"at_s": 0.5, "until_s": 0.6, "volts": 5.0, "ids": [3]}])
    bus = make_bus(faults=faults)
    transact(bus, dxl.write(1, ax12.TORQUE_ENABLE, b"\x01"), 6)
    transact(bus, dxl.write(1, ax12.GOAL_POSITION, (900).to_bytes(2, "little")), 6)
    bus.idle_until(550_000)
    assert transact(bus, dxl.ping(3), 6)[0].code == dxl.ERR_INPUT_VOLTAGE
    bus.idle_until(OVERLOAD_TIME_US + 100_000)
    assert transact(bus, dxl.ping(1), 6)[0].code == dxl.ERR_OVERLOAD
    assert transact(bus, dxl.ping(2), 6)[0].code == dxl.ERR_OVERHEATING
    assert transact(bus, dxl.ping(3), 6)[0].code == 0
    assert faults.counts == {"stall": 1, "overheat": 1, "voltage_sag": 1, "voltage_sag_end": 1}


def test_faults_from_a_scenario_file(tmp_path: Path):
    path = tmp_path / "f.toml"
    path.write_text("[scenario]\nseed = 3\n[faults]\nbit_error_rate = 0.0\n"
                    "unplug = [{id = 5, at_s = 2.0}]\n"
                    "voltage_sag = [{at_s = 1, until_s = 1.5, volts = 6}]\n")
    sc = scenario.load_scenario(path)
    f = Faults(sc.faults, seed=sc.scenario.seed)
    assert f.config.unplug == (FaultEntry(FaultKind.UNPLUG, 2.0, id=5),)
    assert f.config.voltage_sag[0].volts == 6.0 and f.active()
    with pytest.raises(UserError, match="key 'stall.id' is required in a 'stall' entry"):
        scenario.parse({"faults": {"stall": [{"at_s": 1.0}]}})
    with pytest.raises(UserError, match="unknown key 'unplug.when' in a 'unplug' entry"):
        scenario.parse({"faults": {"unplug": [{"id": 1, "at_s": 1.0, "when": 2}]}})
    with pytest.raises(UserError, match="at_s < until_s"):
        scenario.parse({"faults": {"unplug": [{"id": 1, "at_s": 2.0, "until_s": 1.0}]}})
    assert parse_flag("overheat", "3:80:1.5:2") == {"id": 3, "temperature_c": 80.0,
                                                   "at_s": 1.5, "until_s": 2.0}
    with pytest.raises(UserError):
        parse_flag("unplug", "3")


# --- properties -----------------------------------------------------------------------
_chunk = st.one_of(
    st.binary(max_size=40),
    st.builds(lambda i, c, p: dxl.packet(i, c, p), st.sampled_from([1, 2, 17, 0xFE, 99]),
              st.integers(0, 255), st.binary(max_size=12)),
    st.builds(lambda a, d: dxl.write(1, a, d), st.integers(0, 60), st.binary(max_size=4)),
)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(_chunk, st.integers(0, 3000), st.booleans()), max_size=20))
def test_any_byte_stream_never_raises_out_of_the_bus(ops):
    bus = make_bus(4, echo=False)
    for data, wait_us, read in ops:
        bus.master_write(data)
        if read:
            bus.master_read(32, wait_us)
        else:
            bus.idle_until(bus.clock.t_us + wait_us)
        for s in bus.servos:
            for f in ax12.FIELDS:
                assert f[6] <= ax12.get(s.table, f[0], f[2]) <= f[7], f[1]


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(_chunk, st.builds(lambda c: bytes(c[:-1]) + bytes(((c[-1] + 1) % 256,)),
                                            _chunk.filter(len))), max_size=6))
@example([bytes((0xFF, 0xFF, 1, 1, 0xFD)), dxl.ping(1)])    # LEN 1: the parser rejects it
def test_a_burst_of_packets_is_taken_as_the_parser_takes_it_byte_by_byte(chunks):
    """``Bus._deliver`` takes whole packets at the start of a burst at once (a C SDK
    master's SYNC_WRITE and READ back to back): the same servos' state, replies and counts
    as the parser's byte-by-byte path, which a burst of one byte always takes."""
    burst = bytearray(b"".join(chunks))
    whole, by_byte = make_bus(4), make_bus(4)
    whole._deliver(burst, 1000)
    for byte in burst:
        by_byte._deliver(bytearray((byte,)), 1000)
    assert whole.stats == by_byte.stats
    assert [(b.start_us, bytes(b.data)) for b in whole._rx] == \
        [(b.start_us, bytes(b.data)) for b in by_byte._rx]
    assert [bytes(s.table) for s in whole.servos] == [bytes(s.table) for s in by_byte.servos]
    assert whole._parser.pending() == by_byte._parser.pending()


def test_echo_line_collision_is_counted_once_and_heard_corrupted():
    faults = faults_of()
    bus = make_bus(echo=True, faults=faults)
    bus.master_write(dxl.read(1, ax12.PRESENT_POSITION, 2))  # reply due at 580..660
    bus.master_write(dxl.sync_write(ax12.GOAL_POSITION, 2, [(i, b"\x00\x02") for i in range(1, 19)]))
    heard = bus.master_read(200, 2000)
    assert bus.stats["collisions"] == 1 and faults.counts == {"collision": 1}
    assert dxl.status(1, 0, b"\x00\x02") not in heard


def test_writing_id_and_baud():
    bus = make_bus(2)
    (pkt,) = transact(bus, dxl.write(1, ax12.ID, b"\x1e"), 6)
    assert pkt.id == 30  # the status is built after the write, so it carries the new ID
    assert transact(bus, dxl.ping(1), 6) == [] and transact(bus, dxl.ping(30), 6)[0].id == 30
    (pkt,) = transact(bus, dxl.write(30, ax12.BAUD_RATE, b"\x22"), 6)  # 57142 bps
    assert pkt.id == 30  # still at the old rate: the UART switches after the reply
    assert transact(bus, dxl.ping(30), 64) == []  # it now hears garbage and says garbage
    assert transact(bus, dxl.ping(2), 6)[0].id == 2


def test_a_false_header_swallows_packets_until_a_100_ms_gap():
    bus = make_bus(3)
    bus.master_write(b"\xff\xff\x07\xc8")  # announces a 204-byte packet
    assert transact(bus, dxl.ping(2), 6) == []  # swallowed as part of it
    bus.idle_until(bus.clock.t_us + dxl.INTER_BYTE_TIMEOUT_US + 1)
    assert transact(bus, dxl.ping(2), 6)[0].id == 2
