"""``hexhil test`` and expectation files: our firmware's own cases pass, the tactile rule fails
with the rule off (named in the table and the JUnit XML with its measured value), JUnit XML
validates against the common schema, exit codes 0 / 1 / 2, one-line errors naming the key,
the kept trace holds the failure at its moment."""
from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from lxml import etree

from hexhil.expect import spec, steps, verdicts
from hexhil.trace.reader import Trace
from hexhil.protocol.errors import UserError
from conftest import ROOT, hexhil_in_process as hexhil

CASES = sorted(str(p) for p in (ROOT / "tests" / "firmware").glob("*.toml"))
TACTILE = str(ROOT / "tests" / "firmware" / "tactile-low-small.toml")
FAST = ["--python", "cpython-inprocess", "--quiet"]

# The common JUnit schema's core (after the Jenkins/Ant junit XSD): what CI readers rely on.
JUNIT_XSD = b"""<?xml version="1.0"?>
<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema" elementFormDefault="qualified">
  <xs:element name="failure"><xs:complexType><xs:simpleContent>
    <xs:extension base="xs:string">
      <xs:attribute name="message" type="xs:string"/><xs:attribute name="type" type="xs:string"/>
    </xs:extension></xs:simpleContent></xs:complexType></xs:element>
  <xs:element name="system-out" type="xs:string"/>
  <xs:element name="property"><xs:complexType>
    <xs:attribute name="name" type="xs:string" use="required"/>
    <xs:attribute name="value" type="xs:string" use="required"/></xs:complexType></xs:element>
  <xs:element name="properties"><xs:complexType><xs:sequence>
    <xs:element ref="property" minOccurs="0" maxOccurs="unbounded"/></xs:sequence>
  </xs:complexType></xs:element>
  <xs:element name="testcase"><xs:complexType><xs:sequence>
      <xs:element ref="failure" minOccurs="0" maxOccurs="unbounded"/>
      <xs:element ref="system-out" minOccurs="0"/></xs:sequence>
    <xs:attribute name="name" type="xs:string" use="required"/>
    <xs:attribute name="classname" type="xs:string" use="required"/>
    <xs:attribute name="time" type="xs:decimal"/></xs:complexType></xs:element>
  <xs:element name="testsuite"><xs:complexType><xs:sequence>
      <xs:element ref="properties" minOccurs="0"/>
      <xs:element ref="testcase" minOccurs="0" maxOccurs="unbounded"/></xs:sequence>
    <xs:attribute name="name" type="xs:string" use="required"/>
    <xs:attribute name="tests" type="xs:nonNegativeInteger" use="required"/>
    <xs:attribute name="failures" type="xs:nonNegativeInteger" use="required"/>
    <xs:attribute name="errors" type="xs:nonNegativeInteger" use="required"/>
    <xs:attribute name="skipped" type="xs:nonNegativeInteger"/>
    <xs:attribute name="time" type="xs:decimal"/></xs:complexType></xs:element>
  <xs:element name="testsuites"><xs:complexType><xs:sequence>
      <xs:element ref="testsuite" minOccurs="0" maxOccurs="unbounded"/></xs:sequence>
    <xs:attribute name="name" type="xs:string"/>
    <xs:attribute name="tests" type="xs:nonNegativeInteger"/>
    <xs:attribute name="failures" type="xs:nonNegativeInteger"/>
    <xs:attribute name="errors" type="xs:nonNegativeInteger"/>
    <xs:attribute name="time" type="xs:decimal"/></xs:complexType></xs:element>
</xs:schema>"""


def validate_junit(path: Path) -> None:
    schema = etree.XMLSchema(etree.fromstring(JUNIT_XSD))
    doc = etree.parse(str(path))
    assert schema.validate(doc), schema.error_log


def test_our_firmware_passes_its_own_cases(tmp_path: Path) -> None:
    """What ``make test`` runs: every tests/firmware case through ``hexhil test``."""
    proc = hexhil("test", *CASES, *FAST, "--jobs", "2", "--junit", str(tmp_path / "j.xml"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "FAIL" not in proc.stdout
    validate_junit(tmp_path / "j.xml")
    suites = ET.parse(tmp_path / "j.xml").getroot().findall("testsuite")
    assert {s.get("name") for s in suites} == {Path(c).stem for c in CASES}


def test_the_tactile_rule_fails_without_tactile(tmp_path: Path) -> None:
    junit, keep = tmp_path / "j.xml", tmp_path / "kept"
    proc = hexhil("test", TACTILE, *FAST, "--no-tactile", "--junit", str(junit),
                  "--keep-traces", str(keep))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    row = next(line for line in proc.stdout.splitlines() if "tactile rule" in line)
    assert row.rstrip().endswith("FAIL") and "h 0.0" in row and "h_k 0.070" in row
    validate_junit(junit)
    failures = ET.parse(junit).getroot().findall(".//testcase/failure")
    assert [f.get("type") for f in failures] == ["tactile_rule"]
    assert "measured h 0.0" in failures[0].get("message")
    kept = keep / "tactile-low-small.mcap"
    with Trace(kept) as tr:
        notes = [(m.log_time_ns, v) for m, v in tr.decoded(["/expectations"])]
        assert tr.metadata()["failed_expectations"] == "tactile rule"
    assert len(notes) == 1 and notes[0][1]["name"] == "tactile rule"
    moment = float(failures[0].get("message").rsplit("at t=", 1)[1].split(" s")[0])
    assert notes[0][0] == pytest.approx(moment * 1e9, abs=1e6)


def _write(tmp_path: Path, text: str) -> str:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    return str(p)


HEAD = '[case]\nscenario = "%s"\n' % (ROOT / "scenarios" / "flat-tripod.toml")


@pytest.mark.parametrize("body, key", [
    ("", "expect"),
    ('[[expect]]\nkind = "speed"\nmin_m_s = 1\n', "name"),
    ('[[expect]]\nname = "a"\nkind = "sped"\n', "kind"),
    ('[[expect]]\nname = "a"\nkind = "speed"\n', "min_m_s"),
    ('[[expect]]\nname = "a"\nkind = "speed"\nmin_m_s = "fast"\n', "min_m_s"),
    ('[[expect]]\nname = "a"\nkind = "displacement"\ndx_m = [1]\n', "dx_m"),
    ('[[expect]]\nname = "a"\nkind = "displacement"\ndx_m = [2, 1]\n', "dx_m"),
    ('[[expect]]\nname = "a"\nkind = "displacement"\nwindow_s = [0, 1]\n', "displacement"),
    ('[[expect]]\nname = "a"\nkind = "speed"\nmin_m_s = 1\nwindow_s = "all"\n', "window_s"),
    ('[[expect]]\nname = "a"\nkind = "speed"\nmin_m_s = 1\ncolour = 1\n', "colour"),
    ('[[expect]]\nname = "a"\nkind = "protocol"\nallow = ["typo"]\n', "allow"),
    ('[[expect]]\nname = "a"\nkind = "fault_response"\nfault = "fire"\nresponse = "safe_stop"'
     '\nwithin_s = 1\n', "fault"),
    ('[[expect]]\nname = "a"\nkind = "signal"\ntopic = "/servos"\nfield = "x"\nstat = "at"'
     '\nlimit = [0, 1]\n', "at_s"),
    ('[[expect]]\nname = "a"\nkind = "can"\nmessage = "heartbeat"\nsignals = { state = 2 }\n',
     "signals.state"),
])
def test_a_malformed_file_is_one_line_naming_the_key(tmp_path: Path, body: str, key: str) -> None:
    path = _write(tmp_path, HEAD + body)
    proc = hexhil("test", path, *FAST)
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and path in lines[0] and key in lines[0], proc.stderr


SC = 'scenario = "%s"\n' % (ROOT / "scenarios" / "flat-tripod.toml")
NO_EXC = '[[expect]]\nname = "a"\nkind = "no_exception"\n'


@pytest.mark.parametrize("text, key", [
    ("[case]\n" + SC + "colour = 1\n" + NO_EXC, "case.colour"),
    ("[case]\n" + SC + 'send = [{ at_s = 1, message = "nope" }]\n' + NO_EXC, "case.send[0]"),
    ("[case]\n" + SC + "send = [{ at_s = 1, message = 3 }]\n" + NO_EXC,
     "key 'case.send[0].message' must be"),
    (NO_EXC, "case.scenario"),
    ("[case]\n" + SC + 'python = "java"\n' + NO_EXC, "case.python"),
    ("x = = 1", "not valid TOML"),
])
def test_case_table_errors_name_the_key(tmp_path: Path, text: str, key: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(UserError) as info:
        spec.load(path)
    assert key in str(info.value) and str(info.value).count(path) == 1, info.value


def test_field_values_walk_dotted_paths_indices_and_stars() -> None:
    msg = {"servos": [{"id": 1, "t": 30.0, "on": True}, {"id": 2, "t": 40.0, "on": False}]}
    assert verdicts.field_values(msg, "servos[*].t") == [30.0, 40.0]
    assert verdicts.field_values(msg, "servos[1].t") == [40.0]
    assert verdicts.field_values(msg, "servos[0].on") == [1.0]
    assert verdicts.field_values(msg, "servos[5].t") == []


def test_step_extraction_on_a_synthetic_track() -> None:
    """A foot that rises 3 cm while moving 5 cm forward: one step of that size."""
    times = [0.1 * k for k in range(30)]
    track = []
    for k, t in enumerate(times):
        u = (t - 1.0) / 1.0
        z = -0.085 + (0.03 * math.sin(u * math.pi) if 0 < u < 1 else 0.0)
        x = 0.2 + (0.05 * u if 0 < u < 1 else (0.05 if u >= 1 else 0.0))
        track.append((x, 0.0, z))
    (s,) = steps.steps(times, track, 0, 0.0)
    assert s.height_m == pytest.approx(0.03, abs=1e-3)
    assert s.length_m == pytest.approx(0.05, abs=1e-6)
    press = steps.presses([(0.5, 0, True), (0.6, 0, False)], 3.0)
    assert steps.steps_after_presses([s], press, 0.04, 0.0, 3.0) == [s]
    assert steps.steps_after_presses([s], press, 0.2, 0.0, 3.0) == []  # bounce: too short


def test_repeats_run_successive_seeds() -> None:
    from hexhil.expect import case_runs

    case = spec.load(TACTILE)
    jobs = case_runs.jobs_for([case], repeat=3, python="cpython-inprocess")
    assert [(j.label, j.seed) for j in jobs] == [
        (f"{case.name}#{k}", case.seed + k) for k in range(3)]


def test_wrong_expectations_fail_with_their_measured_values(tmp_path: Path) -> None:
    """Every kind can fail: the unplug case's run against expectations it does not meet."""
    from hexhil.expect import case_runs

    wrong = [
        {"name": "ride", "kind": "fault_response", "fault": "unplug",
         "response": "ride_through", "within_s": 4.0},
        {"name": "heat", "kind": "fault_response", "fault": "overheat",
         "response": "safe_stop", "within_s": 1.0},
        {"name": "fast beat", "kind": "can", "message": "heartbeat", "rate_hz": [20, 30]},
        {"name": "still walking", "kind": "can", "message": "heartbeat", "window_s": [7, 9],
         "signals": {"state": [2, 2]}},
        {"name": "far", "kind": "displacement", "dx_m": [1, 2]},
        {"name": "sideways", "kind": "heading", "direction_deg": [80, 100]},
        {"name": "fast", "kind": "speed", "min_m_s": 0.5},
        {"name": "high", "kind": "pose", "z_m": {"min": 0.5}},
        {"name": "cold", "kind": "servo_limits", "temperature_c": {"max": 20}},
        {"name": "tactile", "kind": "tactile_rule", "max_obstacle_height_m": 0.05},
        {"name": "count", "kind": "signal", "topic": "/can/heartbeat", "field": "state",
         "stat": "edges", "limit": [0, 0]},
    ]
    case = spec.load(ROOT / "tests" / "firmware" / "unplug.toml")
    case = dataclasses.replace(case, expectations=tuple(
        spec.expectation("test", e, i) for i, e in enumerate(wrong)))
    r = case_runs.run_case(case_runs.CaseRun(case, case.seed, "wrong", python="cpython-inprocess",
                                       keep_dir=str(tmp_path)))
    got = {o.name: o for o in r.outcomes}
    assert [o.name for o in r.outcomes if o.passed] == []
    assert got["ride"].measured.startswith("stopped 2.9")
    assert got["heat"].measured == "no overheat fault in the window"
    assert got["still walking"].t_s is not None and got["still walking"].t_s >= 7
    assert got["tactile"].measured == "0 steps after a switch press"
    assert got["count"].value >= 1   # walking -> safe stop
    assert Path(r.trace).exists()
