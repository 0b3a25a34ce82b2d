"""A logic analyser's capture of the servo line (sigrok-cli's .sr): imported with its byte
times, its master checked (our firmware's, the stock dynamixel-sdk's, one moved into an
EEPROM wait), Protocol 1.0 and 2.0; bad captures are one line, exit 2."""
from __future__ import annotations

import json
import signal
import subprocess
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import uart_wave
from hexhil.hil import scenario
from hexhil.hil.run.lockstep import Simulator
from hexhil.trace import recorder as rec
from hexhil.protocol.dynamixel import ax12
from robot_logs import (BAUD, HEXHIL, RATE_HZ, ROOT, cli, refused, run, run_sr,  # noqa: F401
                        serial_bursts, streams)


def test_a_sigrok_capture_imports_as_the_lines_bytes_at_their_times(run, run_sr, capsys):
    with zipfile.ZipFile(run_sr) as z:   # sigrok-cli's own writer made it
        assert "metadata" in z.namelist() and any(n.startswith("logic-1") for n in z.namelist())
    out = run_sr.with_name("imported.mcap")
    rc, said, err = cli(capsys, "trace", "import", run_sr, "--out", out, "--json")
    assert rc == 0, err
    r = json.loads(said.strip().splitlines()[-1])
    assert (r["baud"], r["protocol"], r["direction_channel"], r["framing_errors"]) == \
        (BAUD, 1, "2", 0)
    original, imported = serial_bursts(run), serial_bursts(out)
    assert streams(imported) == streams(original)
    starts = {t for t, _, _ in original}
    assert all(t in starts for t, _, _ in imported)   # every byte time kept to the us


def test_without_a_direction_channel_the_packets_say_who_sent(run, tmp_path, capsys):
    wave = uart_wave.samples(serial_bursts(run), BAUD, RATE_HZ, direction=False)
    sr = uart_wave.write_sr(tmp_path / "one_wire.sr", wave, RATE_HZ, channels=1)
    out = tmp_path / "one_wire.mcap"
    rc, said, err = cli(capsys, "trace", "import", sr, "--out", out)
    assert rc == 0, err
    assert streams(serial_bursts(out)) == streams(serial_bursts(run))


# -- the master check on a capture ----------------------------------------------------------
def test_our_firmwares_captured_line_passes_the_master_check(run_sr, capsys):
    rc, said, err = cli(capsys, "conformance", "--capture", run_sr, "--json")
    assert rc == 0, said + err
    r = json.loads(said.strip().splitlines()[-1])
    assert r["ok"] and r["violations"]["total"] == 0 and r["servos"] == list(range(1, 19))
    assert r["line"]["return_delay_us"]["1"]["max"] == 500    # the AX-12's default 500 us


@pytest.fixture(scope="module")
def sdk_session(tmp_path_factory) -> Path:
    """The stock dynamixel-sdk on `hexhil bus --pty`, recorded by the bus: pings, an EEPROM
    write (Return Delay Time) with the wait it needs, then a goal written and read back."""
    import dynamixel_sdk as sdk
    import dynamixel_sdk.port_handler

    path = tmp_path_factory.mktemp("sdk") / "bus.mcap"
    mp = pytest.MonkeyPatch()
    # RX timeout 2 x LATENCY_TIMER + 2 ms, as tests/test_sdk_pty.py: a shared machine may
    # not schedule the server for a while
    mp.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", 50)
    proc = subprocess.Popen([*HEXHIL, "bus", "--pty", "--servos", "3", "--out", str(path)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline().strip()
        assert line.startswith("pty: "), (line, proc.stderr.read() if proc.poll() else "")
        port = sdk.PortHandler(line.split(": ", 1)[1])
        assert port.openPort() and port.setBaudRate(BAUD)
        ph = sdk.PacketHandler(1.0)
        for i in (1, 2, 3):
            assert ph.ping(port, i)[1] == sdk.COMM_SUCCESS
        assert ph.write1ByteTxRx(port, 1, ax12.RETURN_DELAY_TIME, 100)[0] == sdk.COMM_SUCCESS
        time.sleep(0.03)                      # the EEPROM write's wait, and more
        assert ph.write2ByteTxRx(port, 1, ax12.GOAL_POSITION, 600)[0] == sdk.COMM_SUCCESS
        assert ph.read2ByteTxRx(port, 1, ax12.GOAL_POSITION)[:2] == (600, sdk.COMM_SUCCESS)
        port.closePort()
    finally:
        mp.undo()
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, out + err
    return path


def _sdk_capture(bursts, path: Path) -> Path:
    wave = uart_wave.samples(bursts, BAUD, RATE_HZ)
    return uart_wave.write_sr(path, wave, RATE_HZ, channels=1)


def test_the_stock_sdks_captured_master_passes(sdk_session, capsys):
    sr = _sdk_capture(serial_bursts(sdk_session), sdk_session.with_name("sdk.sr"))
    rc, said, err = cli(capsys, "conformance", "--capture", sr)
    assert rc == 0, said + err
    assert "master violations: none" in said and "servos 1,2,3" in said
    assert "id 1 200-500 us" in said   # its return delay, before and after the EEPROM write


def _packets(bursts):
    """The bursts as one a packet (a loaded host may hand the real-time bus a packet in two
    reads, or two in one): each direction's run of bytes cut at its packets."""
    from hexhil.dynamixel.decode import packet_spans

    runs = []
    for t, d, data in bursts:
        if runs and runs[-1][1] == d:
            runs[-1][2] += data
        else:
            runs.append([t, d, bytearray(data)])
    return [(t + off * 10, d, bytes(data[off:off + n]))
            for t, d, data in runs for off, n, _ in packet_spans(bytes(data), 1)]


def test_a_write_moved_into_the_eeprom_wait_fails_named(sdk_session, capsys):
    bursts = _packets(serial_bursts(sdk_session))
    goal = next(k for k, (_, d, data) in enumerate(bursts)
                if d == "tx" and data[4] == 3 and data[5] == ax12.GOAL_POSITION)
    eeprom = next(k for k, (_, d, data) in enumerate(bursts)
                  if d == "tx" and data[4] == 3 and data[5] == ax12.RETURN_DELAY_TIME)
    # the goal write and its status, moved to 1 ms after the EEPROM write's status
    t_status = bursts[eeprom + 1][0]
    shift = t_status + 1_000 - bursts[goal][0]
    moved = [(t + shift, d, data) for t, d, data in bursts[goal:goal + 2]]
    rest = bursts[:goal] + bursts[goal + 2:]
    sr = _sdk_capture(sorted(rest + moved), sdk_session.with_name("moved.sr"))
    rc, said, err = cli(capsys, "conformance", "--capture", sr)
    assert rc == 1, said + err
    assert "eeprom_busy: WRITE id 1 Goal Position (30) = 600 (WRITE while id 1 writes its " \
           "EEPROM)" in said
    assert "master violations: eeprom_busy 1" in said


# -- every import checked ----------------------------------------------------------------
def test_a_truncated_capture_is_one_line(run_sr, tmp_path, capsys):
    cut = tmp_path / "cut.sr"
    cut.write_bytes(run_sr.read_bytes()[: run_sr.stat().st_size // 2])
    err = refused(capsys, "trace", "import", cut, "--out", tmp_path / "x.mcap")
    assert "truncated" in err
    assert not (tmp_path / "x.mcap").exists() and not (tmp_path / "x.mcap.partial").exists()
    assert "truncated" in refused(capsys, "conformance", "--capture", cut)


def test_a_capture_at_the_wrong_sample_rate_or_baud_is_one_line(run, tmp_path, capsys):
    bursts = serial_bursts(run)[:40]
    wave = uart_wave.samples(bursts, BAUD, RATE_HZ)
    mislabelled = uart_wave.write_sr(tmp_path / "five.sr", wave, 5_000_000, channels=1)
    err = refused(capsys, "trace", "import", mislabelled, "--out", tmp_path / "x.mcap")
    assert "baud not found" in err and "625" in err     # 1 Mbit/s read at 5/8 of its rate
    slow = uart_wave.write_sr(tmp_path / "slow.sr", uart_wave.samples(bursts, BAUD, 2_000_000),
                              2_000_000, channels=1)
    assert "too low" in refused(capsys, "trace", "import", slow, "--out", tmp_path / "x.mcap")
    odd = uart_wave.write_sr(tmp_path / "odd.sr", uart_wave.samples(bursts, 700_000, RATE_HZ),
                             RATE_HZ, channels=1)
    assert "baud not found" in refused(capsys, "trace", "import", odd, "--out",
                                        tmp_path / "x.mcap")


def test_a_protocol_2_line_imports_replays_and_passes(tmp_path, capsys):
    """X-series servos (Protocol 2.0, CRC and stuffing) on one wire: the capture is told
    apart by its headers, its status packets by their instruction 0x55."""
    path = tmp_path / "x.mcap"
    s = {section: {} for section in scenario.SCHEMA}
    s["bus"] = {"model": "xl430-w250"}
    with rec.Recorder(path, {"scenario": "x"}, protocol=2) as r:
        assert Simulator(s, seed=0, recorder=r).run(duration_s=0.3,
                                                     python="micropython").exit_code == 0
    sr = uart_wave.write_sr(tmp_path / "x.sr", uart_wave.samples(serial_bursts(path), BAUD, RATE_HZ),
                            RATE_HZ, channels=1)
    out = tmp_path / "imported.mcap"
    rc, said, err = cli(capsys, "trace", "import", sr, "--out", out)
    assert rc == 0 and "Protocol 2.0" in said, said + err
    assert streams(serial_bursts(out)) == streams(serial_bursts(path))
    rc, said, err = cli(capsys, "conformance", "--capture", sr)
    assert rc == 0 and "(xl430-w250)" in said and "master violations: none" in said, said + err
    rc, said, err = cli(capsys, "replay", out)
    assert rc == 0 and said.startswith("identical"), said + err


def test_a_wide_capture_in_several_chunks_reads_whole(run, tmp_path, capsys):
    """Nine channels (two bytes a sample) and more samples than one chunk of sigrok's holds:
    the chunks are read in their order, the direction found on the third channel."""
    wave = uart_wave.samples(serial_bursts(run), BAUD, RATE_HZ, direction=True).astype(np.uint16)
    wave |= 1 << 8    # a ninth channel, held high
    raw = tmp_path / "wide.bin"
    raw.write_bytes(wave.astype("<u2").tobytes())
    sr = tmp_path / "wide.sr"
    subprocess.run(["sigrok-cli", "-I", f"binary:numchannels=9:samplerate={RATE_HZ}", "-i",
                    str(raw), "-o", str(sr)], check=True, capture_output=True)
    with zipfile.ZipFile(sr) as z:
        assert len([n for n in z.namelist() if n.startswith("logic-1-")]) > 1
    out = tmp_path / "wide.mcap"
    rc, said, err = cli(capsys, "trace", "import", sr, "--out", out, "--json")
    assert rc == 0, err
    assert json.loads(said.splitlines()[-1])["direction_channel"] == "2"
    assert streams(serial_bursts(out)) == streams(serial_bursts(run))


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rate=st.sampled_from(["8 MHz", "250 kHz", "1 Hz", "0 Hz", "fast", "", "3.5 GHz"]),
       unit=st.sampled_from(["1", "2", "3", "0", "x"]), probes=st.integers(-1, 20),
       samples=st.binary(max_size=4096), names=st.booleans())
def test_a_hostile_sr_file_is_read_or_refused_in_one_line(tmp_path, rate, unit, probes,
                                                          samples, names):
    from hexhil.trace.import_logs import read_servo_line
    from hexhil.protocol.errors import UserError

    path = tmp_path / "hostile.sr"
    meta = f"[device 1]\ncapturefile=logic-1\ntotal probes={probes}\nsamplerate={rate}\n" \
           f"unitsize={unit}\n" + ("probe1=dir\nprobe2=data\n" if names else "")
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("version", "2")
        z.writestr("metadata", meta)
        z.writestr("logic-1-1", samples)
    try:
        line = read_servo_line(path)
    except UserError as exc:
        assert "\n" not in str(exc)
    else:
        assert line.bursts and line.baud > 0




def test_a_damaged_member_of_the_zip_is_one_line(run_sr, tmp_path, capsys):
    """Found by fuzz_logs: a flipped byte inside the metadata (its CRC no longer holds)
    escaped as BadZipFile, a broken deflate stream as zlib.error."""
    data = bytearray(run_sr.read_bytes())
    with zipfile.ZipFile(run_sr) as z:
        info = z.getinfo("metadata")
    data[info.header_offset + 30 + len(info.filename) + 2] ^= 0x55   # inside its data
    bad = tmp_path / "bad.sr"
    bad.write_bytes(bytes(data))
    err = refused(capsys, "trace", "import", bad, "--out", tmp_path / "x.mcap")
    assert "truncated or damaged capture (metadata:" in err
