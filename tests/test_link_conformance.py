"""The link conformance suite (hil/link/client_conformance.py, docs/link.md) against the Python
link client under micropython and CPython, and against a deliberately broken client.

``HEXHIL_LINK_CLIENT="cmd args"`` points the suite at another client instead (run from the
repository root, with HEXHIL_LINK_PORT set by the suite)."""
import os
import shlex
import sys

import pytest

from hexhil.hil.link.firmware_process import firmware_env
from hexhil.hil.link.client_conformance import BURST, SESSIONS, run_suite
from mpy import micropython_binary

CLIENT = "tests/link_clients/python_client.py"
OTHER = os.environ.get("HEXHIL_LINK_CLIENT")
CLIENTS = {"other": shlex.split(OTHER)} if OTHER else {
    "micropython": [micropython_binary(), CLIENT], "cpython": [sys.executable, CLIENT]}
ENV = {k: v for k, v in firmware_env(0).items() if k in ("MICROPYPATH", "PYTHONPATH")}


@pytest.mark.parametrize("client", sorted(CLIENTS))
def test_the_client_conforms(client):
    results = run_suite(CLIENTS[client], ENV)
    failed = [f"{r.name}: {r.detail}" for r in results if not r.passed]
    assert failed == []
    assert len(results) == sum(len(checks) for _, checks in SESSIONS.values())
    assert f"script: split sleep reply: {BURST} CAN frames, in order" in [r.name for r in results]


def test_a_client_that_drops_continued_frames_fails():
    results = run_suite([micropython_binary(), CLIENT, "--drop-more"], ENV)
    failed = [r for r in results if not r.passed]
    assert [r.name for r in failed] == [f"script: split sleep reply: {BURST} CAN frames, in order",
                                        "version_1: version 1: split sleep reply"]
    assert all("expected request M" in r.detail for r in failed)
