"""`hexhil conformance` against our pty bus: all pass, echo stripped, faults caught."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

from conftest import ROOT, hexhil_in_process
from test_sdk_pty import bus_server

CHECKS_PER_SERVO = {"present", "ping_status_format", "read_table", "read_consistency",
                    "bad_checksum_reply", "out_of_range_goal", "action_nothing_registered",
                    "reg_write_action", "angle_limit_error", "status_return_level",
                    "return_delay_timing", "restored"}


def conformance(port: str, *flags: str) -> tuple[int, dict, str]:
    r = hexhil_in_process("conformance", "--port", port, "--json", "--timeout-ms", "500", *flags)
    assert "Traceback" not in r.stderr, r.stderr
    return r.returncode, json.loads(r.stdout.strip().splitlines()[-1]), r.stdout


def test_our_bus_passes_every_check_for_18_servos():
    with bus_server() as path:
        rc, result, out = conformance(path, "--ids", "1-18")
    assert rc == 0 and result["ok"] and result["failed"] == 0 and result["skipped"] == 0, out
    assert result["servos"] == list(range(1, 19)) and not result["echo"]
    for i in range(1, 19):
        assert {c["check"] for c in result["checks"] if c["id"] == i} == CHECKS_PER_SERVO
    assert "216 passed, 0 failed, 0 skipped" in out


def test_scan_and_echo_line_with_original_edition():
    with bus_server("--echo", "--ids", "7,9", "--edition", "original") as path:
        rc, result, out = conformance(path, "--scan-timeout-ms", "30")
    assert rc == 0 and result["echo"] and result["servos"] == [7, 9], out
    assert result["checks"][0]["check"] == "scan"


SLOPPY = textwrap.dedent("""
    import sys
    from hil.servobus.line import Bus
    from hil.clock import VirtualClock
    from hil.servobus.serial_server import RealTimeServer, install_sigterm, Stop
    from hexhil.cli import flush_print
    from hil.servobus.ax12_servo import Servo

    class Sloppy(Servo):  # ignores packets with a bad checksum instead of answering bit 4
        def checksum_error(self, code, t_us):
            return None

    class Hasty(Servo):  # answers at once whatever its Return Delay Time says
        return_delay_us = 0

    install_sigterm()
    try:
        RealTimeServer(Bus([Sloppy(1), Hasty(2)], VirtualClock())).serve_pty(flush_print)
    except Stop:
        pass
""")


def conformance_of(script: str, *flags: str) -> tuple[int, dict, str]:
    """Run ``script`` (a server that prints its pty) and the conformance suite on ids 1-3."""
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, stdout=subprocess.PIPE,
                            text=True)
    try:
        path = proc.stdout.readline().strip().split(": ", 1)[1]
        return conformance(path, "--ids", "1-3", *flags)
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_a_non_conforming_servo_fails_and_exits_1():
    rc, result, out = conformance_of(SLOPPY)
    failed = sorted((c["id"], c["check"]) for c in result["checks"] if c["result"] == "fail")
    assert rc == 1 and not result["ok"]
    assert failed == [(1, "bad_checksum_reply"), (2, "return_delay_timing"), (3, "present")], out
    # a wrong reply is the servo's; silence may be a lost packet or a servo that says nothing
    causes = {(c["id"], c["check"]): c["cause"] for c in result["checks"] if c["result"] == "fail"}
    assert causes == {(1, "bad_checksum_reply"): "no reply", (2, "return_delay_timing"): "servo",
                      (3, "present"): "no reply"}, out
    assert "[not conforming] fastest PING" in out and "[lost reply or silent servo] no reply to PING (3 tries)" in out


def test_lost_replies_are_retried_and_never_blamed_on_the_servo():
    """One status in ten dropped: repeatable instructions are sent again, and what still fails
    is reported as a missing reply, not as a non-conforming servo; identical rows collapse."""
    with bus_server("--ids", "1-3", "--drop-status-rate", "0.1", "--seed", "1") as path:
        rc, result, out = conformance(path, "--ids", "1-3", "--timeout-ms", "50")
    rows = result["checks"]
    assert [c["result"] for c in rows if c["check"] == "present"] == ["pass"] * 3, out
    assert result["passed"] >= 30 and all(c["cause"] == "no reply" for c in rows
                                          if c["result"] == "fail"), out
    assert result["no_reply"] == result["failed"] and rc == (1 if result["failed"] else 0)
    assert "1-3  present                    PASS   answers PING" in out


def test_results_shared_by_servos_are_shown_once_with_their_ids():
    from hexhil.dynamixel.conformance.report import collapse, format_ids

    assert format_ids([5, 1, 2, 3, 7, 8, None]) == "1-3,5,7-8" and format_ids([None]) == "-"
    rows = [{"id": i, "check": c, "result": "pass", "detail": d, "cause": ""}
            for i in (1, 2, 3) for c, d in (("a", "same"), ("b", f"took {i % 2} ms"))]
    assert [(ids, r["check"], r["detail"]) for ids, r in collapse(rows)] == [
        ([1, 2, 3], "a", "same"), ([1, 3], "b", "took 1 ms"), ([2], "b", "took 0 ms")]


QUIET_AND_LOCKED = textwrap.dedent("""
    from hil.servobus.line import Bus
    from hil.clock import VirtualClock
    from hil.servobus.serial_server import RealTimeServer, install_sigterm, Stop
    from hexhil.cli import flush_print
    from hil.servobus.ax12_servo import Servo

    s = [Servo(1), Servo(2), Servo(3)]
    s[0].table[16] = 0  # Status Return Level 0: PING only
    s[1].table[16] = 1  # PING and READ
    s[2].table[47] = 1  # Lock
    install_sigterm()
    try:
        RealTimeServer(Bus(s, VirtualClock())).serve_pty(flush_print)
    except Stop:
        pass
""")


def test_quiet_servos_are_lifted_and_put_back_locked_ones_skipped():
    rc, result, out = conformance_of(QUIET_AND_LOCKED)
    assert rc == 0 and result["failed"] == 0, out
    skipped = sorted((c["id"], c["check"]) for c in result["checks"] if c["result"] == "skip")
    assert skipped == [(3, "angle_limit_error"), (3, "return_delay_timing"),
                       (3, "status_return_level")]
    # "restored" read Status Return Level 1 back, and found READ silent again at level 0
    assert [c["result"] for c in result["checks"] if c["check"] == "restored"] == ["pass"] * 3


def test_unopenable_port_is_a_one_line_user_error():
    r = hexhil_in_process("conformance", "--port", "/dev/does-not-exist")
    assert r.returncode == 2 and r.stderr.startswith("hexhil: cannot open /dev/does-not-exist")
    assert r.stderr.count("\n") == 1
