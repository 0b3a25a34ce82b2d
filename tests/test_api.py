"""The public API (host_tools/__init__.py, docs/api.md): every name resolves and is
documented, a scenario loads typed and frozen, and examples/host_node.py (which uses the
API alone) runs a shipped scenario with its own host node and reads its trace back."""
import builtins
import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest

import hexhil as hx
from conftest import ROOT


def test_every_public_name_resolves_and_is_documented():
    doc = (ROOT / "docs" / "api.md").read_text()
    for name in hx.__all__:
        assert getattr(hx, name) is not None
        assert f"`{name}" in doc, f"docs/api.md does not describe {name}"
    with pytest.raises(AttributeError):
        hx.no_such_name


def test_every_type_the_docs_name_is_exported():
    """A class docs/api.md names (`Name`, `Name(`, `Name.attr`) is importable from hx;
    enum members and the standard library's names are not classes of ours."""
    doc = (ROOT / "docs" / "api.md").read_text()
    named = set(re.findall(r"`([A-Z][a-z][A-Za-z0-9]*)[`(.]", doc)) - {"Enum", "Protocol"}
    named -= set(dir(builtins))
    assert named and not named - set(hx.__all__), sorted(named - set(hx.__all__))


def test_a_host_node_is_anything_with_a_period_and_a_tick():
    class Node:
        period_us = 100_000

        def tick(self, t_us: int) -> None:
            pass

    assert isinstance(Node(), hx.HostNode)
    assert not isinstance(object(), hx.HostNode)


def test_a_scenario_is_typed_frozen_with_its_defaults_applied():
    sc = hx.load_scenario(ROOT / "scenarios" / "faults.toml")
    assert sc.bus.baud == 1_000_000 and sc.bus.servos == 18 and list(sc.bus.ids)[0] == 1
    assert sc.firmware.python is hx.Runtime.MICROPYTHON
    assert sc.world.kind is None and sc.gait.name == "tripod" and sc.gait.period_s > 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.bus.baud = 57_600
    beams = hx.load_scenario(ROOT / "scenarios" / "beams-stiff.toml")
    assert beams.world.kind is hx.WorldKind.BEAMS and beams.beams.hb2_m == beams.beams.hb1_m
    bare = hx.parse_scenario({"world": {}})
    assert bare.world.kind is None and bare.scenario.duration_s == 30.0
    assert hx.parse_scenario({"world": {"terrain": "flat"}}).world.kind is hx.WorldKind.HEXAPOD


def test_a_run_records_its_scenario_so_the_trace_needs_no_file(tmp_path):
    text = (ROOT / "scenarios" / "flat-tripod.toml").read_text()
    path = tmp_path / "gone.toml"
    path.write_text(text)
    out = tmp_path / "run.mcap"
    result = hx.Run(path, seed=5, runtime="cpython-inprocess", duration_s=0.3, trace=out).run()
    assert result.runtime == "cpython-inprocess" and result.sim_time_s == pytest.approx(0.3)
    path.unlink()
    with hx.open_trace(out) as trace:
        sc, seed = hx.scenario_of_trace(trace.metadata(), str(out))
    shipped = hx.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    as_run = shipped.as_toml_data()   # what was run: the seed and duration given written in
    as_run["scenario"] = {**as_run["scenario"], "seed": 5, "duration_s": 0.3}
    assert seed == 5 and sc.as_toml_data() == as_run
    assert (sc.bus, sc.gait, sc.firmware, sc.world) == (shipped.bus, shipped.gait,
                                                       shipped.firmware, shipped.world)


def test_the_example_runs_its_own_host_node_and_reads_the_trace_back(tmp_path):
    out = tmp_path / "host_node.mcap"
    r = subprocess.run([sys.executable, "examples/host_node.py", str(out)], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "scenario flat-tripod (seed 1) under cpython-inprocess: 6.0 s" in r.stdout
    heights = re.search(r"body height: (\d+) samples, mean ([\d.]+) mm", r.stdout)
    assert int(heights[1]) == 60 and 60 < float(heights[2]) < 120
    assert "61 body poses, 1 heading_command frame(s)" in r.stdout
    # the frame the node injected turned the walk off the x axis (flat-tripod walks along it)
    angle = float(re.search(r"at ([-+\d.]+) deg from x", r.stdout)[1])
    assert angle > 10.0
    assert out.stat().st_size > 0


def test_the_grnn_dataset_reads_a_hexhil_run_trace_whose_scenario_file_is_gone(tmp_path):
    from hexhil.papers.tactile_hexapod.grnn.dataset import rows_from_trace

    path = tmp_path / "walk.toml"
    path.write_text('[scenario]\nname = "walk"\nseed = 2\nduration_s = 6.0\n'
                    '[gait]\nname = "tripod"\ndistance_m = 0.2\n[world]\nterrain = "flat"\n')
    out = tmp_path / "walk.mcap"
    hx.Run(path, runtime=hx.Runtime.CPYTHON_INPROCESS, trace=out).run()
    path.unlink()
    rows, facts = rows_from_trace(out)
    assert facts["gait"] == "tripod" and facts["distance_m"] == 0.2 and len(rows) >= 1


def test_a_real_time_run_serves_a_master_on_a_pty_and_records_its_scenario(tmp_path):
    """RealTimeRun (hexhil bus): a master pings servo 1 over the pty; the trace says it was
    a bus run and carries the scenario like a Run's."""
    import threading

    import serial

    from hexhil.protocol.dynamixel import v1 as dxl

    out = tmp_path / "bus.mcap"
    shipped = hx.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    run = hx.RealTimeRun(shipped, 4, trace=str(out), duration_s=1.5)
    ready, where, summary = threading.Event(), [], {}

    def announce(line):
        where.append(line.split(": ", 1)[1])
        ready.set()

    server = threading.Thread(target=lambda: summary.update(result=run.serve(hx.Pty(), announce)))
    server.start()
    assert ready.wait(10)
    with serial.Serial(where[0], 1_000_000, timeout=0.5) as port:
        port.write(dxl.ping(1))
        reply = port.read(6)
    server.join(10)
    assert reply == dxl.status(1, 0, b"")   # ID 1, no error, no parameters
    result = summary["result"]   # a frozen ServeResult, as Run's RunResult
    assert result.bus["replies"] == 1 and result.served_s >= 1.4
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.served_s = 0
    assert result.as_dict()["bus"]["replies"] == 1
    run.close()   # the same close() as Run's, again after serve: nothing left to close
    with hx.open_trace(out) as trace:
        meta = trace.metadata()
        sc, seed = hx.scenario_of_trace(meta, str(out))
    assert meta["command"] == "bus" and meta["firmware_runtime"] == "external"
    as_run = shipped.as_toml_data()   # what was run: its seed written in
    as_run["scenario"] = {**as_run["scenario"], "seed": 4}
    assert seed == 4 and sc.as_toml_data() == as_run


def _blocks(doc: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", doc, re.S)


@pytest.mark.parametrize("n", range(len(_blocks((ROOT / "docs" / "api.md").read_text()))))
def test_the_docs_examples_run_and_print_what_they_say(n: int, tmp_path: Path) -> None:
    """Each Python block of docs/api.md runs as it is; a ``print(...)  # X`` prints X (the
    part after the comment's last colon)."""
    code = _blocks((ROOT / "docs" / "api.md").read_text())[n]
    (tmp_path / "scenarios").symlink_to(ROOT / "scenarios")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    said = [line.split("#", 1)[1].rsplit(": ", 1)[-1].strip()
            for line in code.splitlines() if line.startswith("print(") and "#" in line]
    assert out.stdout.split("\n")[:len(said)] == said


def test_one_result_form_the_tally_holds_the_results_fields():
    """A run's tally is RunResult's fields, mutable (declared once, in RunResult), bar the
    ones the firmware's stats or the host nodes give when it ends."""
    from hexhil.hil.run_result import RunTally

    tally = RunTally("micropython")
    after = {"cycles", "overruns", "host_nodes"}
    assert set(vars(tally)) == {f.name for f in dataclasses.fields(hx.RunResult)} - after
    tally.exceptions.append("ValueError: boom")
    tally.count_can(0x700)
    tally.firmware = {"cycles": 3, "overruns": 1, "state": "walking"}
    result = tally.result()
    assert (result.cycles, result.overruns, result.exceptions) == (3, 1, ("ValueError: boom",))
    assert result.can_frames == {0x700: 1} and result.firmware.state == "walking"
    with pytest.raises(TypeError):
        result.can_frames[0x700] = 2   # frozen, as the result is
