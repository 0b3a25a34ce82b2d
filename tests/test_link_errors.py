"""The link's refusals (docs/link.md): a hello of another version and a message of an
unknown op get an error reply, and each side says so in one line; the real firmware
handles a refused or other-version hello and a closed link the same way."""
import re
import sys

import pytest

from hexhil.hil.link import client_conformance as lc
from hexhil.hil.link.firmware_process import firmware_env
from hexhil.hil.scenario import SCHEMA
from hexhil.hil.run.lockstep import Simulator
from hexhil.protocol.errors import UserError
from mpy import micropython_binary

ENV = {k: v for k, v in firmware_env(0).items() if k in ("MICROPYPATH", "PYTHONPATH")}
RUNTIMES = {"micropython": micropython_binary, "cpython": lambda: sys.executable}


def _bare():
    sc = {s: {} for s in SCHEMA}
    sc["_path"] = "<test>"
    return sc


@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_the_host_refuses_a_firmware_of_another_version(runtime):
    cmd = [RUNTIMES[runtime](), "tests/link_clients/firmware_other_version.py"]
    with pytest.raises(UserError, match="^firmware link: link version mismatch: the firmware "
                       "speaks version 3, this host speaks 1 and 2$"):
        Simulator(_bare(), seed=1).run(0.2, command=cmd)


@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
@pytest.mark.parametrize("op, payload, said", [
    ("7a", "3f3f", "unknown message op 0x7a"),
    ("43", "2301" + "09" + "00" * 9, "malformed CAN message (12 bytes)"),
    ("43", "230102" + "00", "malformed CAN message (4 bytes)"),
    ("45", "", "malformed event (no kind byte)"),
    ("45", "03" + b"{bad".hex(), "malformed event 3: "),
    ("54", "0000", "malformed timed event (2 bytes)"),
    ("54", "00" * 8 + "03" + b"{bad".hex(), "malformed event 3: "),
    ("58", "0008", "malformed message: "),
    ("52", "01", "malformed reads (1 bytes, 13 announced)"),
    ("52", "010106010000" + "0e00" + "00000000" + "00", "read 0 skips on read 0, not an "
                                                        "earlier one"),
    ("52", "0101060100ff" + "0e00" + "00000000" + "05", "malformed reads (13 bytes, 18 "
                                                        "announced)"),
    ("52", "00 v1", "unknown message op 0x52"),   # R is version 2's
])
def test_the_host_refuses_an_unknown_or_malformed_message(runtime, op, payload, said):
    cmd = [RUNTIMES[runtime](), "tests/link_clients/raw_message.py", op, *payload.split()]
    with pytest.raises(UserError, match="^firmware link: " + re.escape(said)):
        Simulator(_bare(), seed=1).run(0.2, command=cmd)


@pytest.mark.parametrize("session", ["refused_version", "other_version", "closed_link"])
def test_the_firmware_reports_a_failed_link_in_one_line(session):
    steps = []
    s = lc.Session([micropython_binary(), "-m", "firmware.main"], ENV, 30.0)
    try:
        lc.SESSIONS[session][0](s, lambda: steps.append(session))
    finally:
        s.close()
    assert steps == [session]

