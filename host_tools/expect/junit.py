"""JUnit XML of expectation results, in the common schema CI systems read (Jenkins, GitLab,
GitHub test reporters): ``testsuites`` > one ``testsuite`` a case run > one ``testcase`` an
expectation, with a ``failure`` (message: measured against limit) when it failed, and an
``error`` testcase (the reason, the firmware's last lines) when the firmware crashed, hung,
exited early or never started. A suite's time is its run's wall time; a testcase's, the
time its own evaluation took (the run is shared, so it is not split among them)."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Sequence

from hexhil.expect.case_runs import CaseResult
from hexhil.expect.verdicts import ENDING
from hexhil.protocol.errors import BadFile


def to_xml(results: Sequence[CaseResult], name: str = "hexhil test") -> ET.ElementTree:
    total = sum(len(r.outcomes) for r in results)
    errors = sum(o.name == ENDING for r in results for o in r.outcomes)
    failures = sum(not o.passed for r in results for o in r.outcomes) - errors
    wall = sum(float(r.summary.get("wall_time_s") or 0.0) for r in results)
    root = ET.Element("testsuites", name=name, tests=str(total), failures=str(failures),
                      errors=str(errors), time=f"{wall:.3f}")
    for r in results:
        n_err = sum(o.name == ENDING for o in r.outcomes)
        n_fail = sum(not o.passed for o in r.outcomes) - n_err
        run_s = float(r.summary.get("wall_time_s") or 0.0)
        suite = ET.SubElement(root, "testsuite", name=r.label, tests=str(len(r.outcomes)),
                              failures=str(n_fail), errors=str(n_err), skipped="0",
                              time=f"{run_s:.3f}")
        props = ET.SubElement(suite, "properties")
        for key in ("scenario", "seed", "firmware_runtime", "sim_time_s", "serial_digest"):
            ET.SubElement(props, "property", name=key, value=str(r.summary.get(key, "")))
        ending = r.summary.get("ending")
        if ending is not None:
            ET.SubElement(props, "property", name="firmware_ending", value=ending["kind"])
        if "tactile" in r.summary:   # what the run was: the tactile rule and every override
            ET.SubElement(props, "property", name="tactile", value=str(r.summary["tactile"]))
        for key, value in sorted(r.summary.get("overrides", {}).items()):
            ET.SubElement(props, "property", name=f"override.{key}", value=str(value))
        if r.trace:
            ET.SubElement(props, "property", name="trace", value=r.trace)
        for o in r.outcomes:
            tc = ET.SubElement(suite, "testcase", classname=r.label, name=o.name,
                               time=f"{o.time_s:.3f}")
            text = f"{o.kind}: measured {o.measured}; limit {o.limit}"
            if o.t_s is not None:
                text += f"; at t={o.t_s:.3f} s"
            if o.name == ENDING:   # the firmware crashed, hung, exited early, never started
                error = ET.SubElement(tc, "error", message=o.measured, type=o.kind)
                error.text = "\n".join([o.measured, *r.summary["ending"]["last_lines"]]
                                       + ([f"trace: {r.trace}"] if r.trace else []))
            elif not o.passed:
                failure = ET.SubElement(tc, "failure", message=text, type=o.kind)
                failure.text = text + (f"\ntrace: {r.trace}" if r.trace else "")
            ET.SubElement(tc, "system-out").text = text
    ET.indent(root)
    return ET.ElementTree(root)


def write(results: Sequence[CaseResult], path: str | Path) -> None:
    try:
        to_xml(results).write(path, encoding="utf-8", xml_declaration=True)
    except OSError as exc:
        raise BadFile(f"the JUnit report {path}: cannot write ({exc.strerror})") from None
