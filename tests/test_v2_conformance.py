"""`hexhil conformance --protocol 2` against our Protocol 2.0 pty bus: all pass; servos with
a deliberate fault (no byte stuffing, a wrong CRC, a hasty reply) fail, the rule named."""
from __future__ import annotations

import textwrap

from test_conformance_checker import conformance, conformance_of
from test_sdk_pty import bus_server


def test_our_xl430_bus_passes_every_check() -> None:
    with bus_server("--model", "xl430-w250", "--ids", "1-4") as path:
        rc, result, out = conformance(path, "--protocol", "2", "--ids", "1-4")
    assert rc == 0 and result["ok"] and result["failed"] == 0 and result["skipped"] == 0, out
    assert result["servos"] == [1, 2, 3, 4] and result["protocol"] == 2
    names = {c["check"] for c in result["checks"]}
    assert {"byte_stuffing", "no_reply_to_bad_crc", "eeprom_lock", "status_return_level",
            "return_delay_timing", "sync_read_order", "fast_sync_read", "bulk_read_order",
            "fast_bulk_read"} <= names


FAULTY = textwrap.dedent("""
    from hil.servobus.protocols.v2 import Bus2
    from hil.clock import VirtualClock
    from hil.servobus.serial_server import RealTimeServer, install_sigterm, Stop
    from hexhil.cli import flush_print
    from hil.servobus.xseries_servo import XSeriesServo
    from protocol.dynamixel import v2 as dx2

    def unstuffed(reply):  # the same packet as sent by a servo that forgets to stuff
        p = dx2.Parser().feed(reply)[0]
        body = bytes((0xFF, 0xFF, 0xFD, 0, p.id)) + (len(p.params) + 3).to_bytes(2, "little") \\
            + bytes((p.instr,)) + p.params
        return body + dx2.crc16(body, 0, len(body)).to_bytes(2, "little")

    class NoStuffing(XSeriesServo):
        def handle(self, instr, params, broadcast, t_us):
            reply = super().handle(instr, params, broadcast, t_us)
            return None if reply is None else unstuffed(reply)

    class WrongCrc(XSeriesServo):
        def ping_reply(self):
            r = bytearray(super().ping_reply())
            r[-1] ^= 0x55
            return bytes(r)

    class Hasty(XSeriesServo):  # answers at once whatever its Return Delay Time says
        return_delay_us = 0

    servos = [NoStuffing(1), WrongCrc(2), Hasty(3)]
    for s in servos:
        s.table[8] = 3  # 1 Mbps
    install_sigterm()
    try:
        RealTimeServer(Bus2(servos, VirtualClock())).serve_pty(flush_print)
    except Stop:
        pass
""")


def test_faulty_servos_fail_naming_the_rule() -> None:
    rc, result, out = conformance_of(FAULTY, "--protocol", "2")
    failed = sorted((c["id"], c["check"]) for c in result["checks"] if c["result"] == "fail")
    assert rc == 1 and not result["ok"]
    assert (1, "byte_stuffing") in failed and (2, "status_crc") in failed, out
    assert (3, "return_delay_timing") in failed, out
    assert not [f for f in failed if f[0] == 1 and f[1] != "byte_stuffing"], out
