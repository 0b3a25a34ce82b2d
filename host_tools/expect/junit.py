"""JUnit XML of expectation results, in the common schema CI systems read (Jenkins, GitLab,
GitHub test reporters): ``testsuites`` > one ``testsuite`` a case run > one ``testcase`` an
expectation, with a ``failure`` (message: measured against limit) when it failed. A
suite's time is its run's wall time; a testcase's, the time its own evaluation took (the
run is shared, so it is not split among them)."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Sequence

from host_tools.expect.case_runs import CaseResult
from protocol.errors import UserError


def to_xml(results: Sequence[CaseResult], name: str = "hexhil test") -> ET.ElementTree:
    total = sum(len(r.outcomes) for r in results)
    failures = sum(not o.passed for r in results for o in r.outcomes)
    wall = sum(float(r.summary.get("wall_time_s") or 0.0) for r in results)
    root = ET.Element("testsuites", name=name, tests=str(total), failures=str(failures),
                      errors="0", time=f"{wall:.3f}")
    for r in results:
        n_fail = sum(not o.passed for o in r.outcomes)
        run_s = float(r.summary.get("wall_time_s") or 0.0)
        suite = ET.SubElement(root, "testsuite", name=r.label, tests=str(len(r.outcomes)),
                              failures=str(n_fail), errors="0", skipped="0",
                              time=f"{run_s:.3f}")
        props = ET.SubElement(suite, "properties")
        for key in ("scenario", "seed", "firmware_runtime", "sim_time_s", "serial_digest"):
            ET.SubElement(props, "property", name=key, value=str(r.summary.get(key, "")))
        if r.trace:
            ET.SubElement(props, "property", name="trace", value=r.trace)
        for o in r.outcomes:
            tc = ET.SubElement(suite, "testcase", classname=r.label, name=o.name,
                               time=f"{o.time_s:.3f}")
            text = f"{o.kind}: measured {o.measured}; limit {o.limit}"
            if o.t_s is not None:
                text += f"; at t={o.t_s:.3f} s"
            if not o.passed:
                failure = ET.SubElement(tc, "failure", message=text, type=o.kind)
                failure.text = text + (f"\ntrace: {r.trace}" if r.trace else "")
            ET.SubElement(tc, "system-out").text = text
    ET.indent(root)
    return ET.ElementTree(root)


def write(results: Sequence[CaseResult], path: str | Path) -> None:
    try:
        to_xml(results).write(path, encoding="utf-8", xml_declaration=True)
    except OSError as exc:
        raise UserError(f"the JUnit report {path}: cannot write ({exc.strerror})") from None
