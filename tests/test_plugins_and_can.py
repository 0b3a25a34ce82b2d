"""The papers' features found as plug-ins (the ``hexhil.plugins`` entry point group, as
pytest and python-can find theirs), so every shipped scenario runs through ``Run`` with no
import of its own; CAN through python-can's ``can.Message``, counted by arbitration id."""
from __future__ import annotations

import subprocess
import sys
from importlib.metadata import entry_points

import can
import pytest

import hexhil as hx
from hexhil.protocol import can_frames as cf
from conftest import ROOT


def test_the_papers_are_entry_points() -> None:
    found = {ep.name: ep.value for ep in entry_points(group="hexhil.plugins")}
    assert found == {"beam_traversal": "hexhil.papers.beam_traversal",
                     "tactile_hexapod": "hexhil.papers.tactile_hexapod"}


def test_a_beams_scenario_runs_through_run_with_no_import() -> None:
    script = ("import sys, hexhil as hx\n"
              "assert 'hexhil.papers' not in sys.modules\n"
              "r = hx.Run('scenarios/beams-stiff.toml', duration_s=0.1).run()\n"
              "print(sorted(r.host_nodes)[:3], 'hexhil.papers' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "['barrier_J', 'control_start', 'delay_ms'] True"   # the traversal's


def test_can_goes_in_as_a_message_and_is_counted_by_id() -> None:
    run = hx.Run("scenarios/flat-tripod.toml", runtime=hx.Runtime.CPYTHON_INPROCESS,
                 duration_s=0.5)
    port = run.can_endpoint()
    sent = []

    class Steer:
        period_us = 100_000

        def tick(self, t_us: int) -> None:
            msg = hx.can_message("heading_command", direction_rad=0.1)
            assert isinstance(msg, can.Message)
            port.send(msg)
            sent.append(msg.arbitration_id)

    run.add_node(Steer())
    result = run.run()
    assert sent and sent[0] == cf.ID_HEADING_COMMAND
    heard = {m.arbitration_id for m in port.frames()}
    assert cf.ID_HEARTBEAT in heard
    assert result.can_frames[cf.ID_HEARTBEAT] >= 4     # 10 Hz, keyed as python-can's ids
    assert all(isinstance(k, int) for k in result.can_frames)


@pytest.mark.parametrize("msg", [
    can.Message(arbitration_id=0x1ABCDE, data=b"\x01", is_extended_id=True),
    can.Message(arbitration_id=0x100, is_remote_frame=True, is_extended_id=False),
])
def test_a_frame_a_run_cannot_carry_is_one_line(msg: can.Message) -> None:
    run = hx.Run("scenarios/flat-tripod.toml", runtime=hx.Runtime.CPYTHON_INPROCESS,
                 duration_s=0.1)
    with run, pytest.raises(hx.UserError, match="standard 11-bit data frames"):
        run.send_can(msg)
