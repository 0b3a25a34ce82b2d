"""The hexhil pytest plugin (entry point pytest11): the example tests pass, and a failing
check reports measured value and limit, in the terminal and in ``--junitxml``, with the
trace (the failure written into it) named."""
from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from hexhil.trace.reader import Trace
from conftest import ROOT

EXAMPLE = ROOT / "examples" / "test_firmware_example.py"


def _pytest(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", str(EXAMPLE), "-p", "no:cacheprovider",
                           "--hexhil-runtime", "cpython-inprocess", *argv],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_a_failing_check_reports_measured_value_and_limit(tmp_path: Path) -> None:
    junit = tmp_path / "out.xml"
    proc = _pytest("-k", "tactile", "--runxfail", "--junitxml", str(junit),
                   "--hexhil-keep", str(tmp_path / "kept"))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "1 failed, 1 passed" in proc.stdout
    assert "tactile rule: measured h 0.0" in proc.stdout and "limit h_k 0.070" in proc.stdout
    assert "hexhil traces" in proc.stdout
    cases = ET.parse(junit).getroot().findall(".//testcase")
    failed = [c for c in cases if c.find("failure") is not None]
    assert len(cases) == 2 and len(failed) == 1
    message = failed[0].find("failure").get("message")
    assert "measured h 0.0" in message and "limit h_k 0.070" in message
    assert "record_property is incompatible" not in proc.stdout + proc.stderr
    # pytest's default JUnit family (xunit2) has no testcase properties: the suite names them
    traces = [p.get("value") for p in ET.parse(junit).getroot().iter("property")
              if p.get("name").startswith("trace ")
              and p.get("name").endswith("::" + failed[0].get("name"))]
    annotated = [t for t in traces if "failed" in t]
    assert annotated, traces
    with Trace(annotated[0]) as tr:
        assert [v["name"] for _, v in tr.decoded(["/expectations"])] == ["tactile rule"]
    assert list((tmp_path / "kept").glob("*.mcap"))


def test_the_example_passes_as_shipped() -> None:
    proc = _pytest("-k", "not tactile")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "5 passed" in proc.stdout


def test_the_firmware_option_reaches_every_run() -> None:
    proc = _pytest("-k", "flat_walk and tripod", "--hexhil-firmware", "nowhere.py")
    assert proc.returncode == 1 and "firmware nowhere.py: not a file" in proc.stdout
