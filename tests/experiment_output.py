"""The one output style of ``hexhil experiment NAME``, checked the same way for
every experiment: a headline, indented headline figures, where the report and the figures
are, the JSON summary last with --json; the Markdown report stays in its file."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def check_output(stdout: str, name: str, out: Path) -> dict[str, Any]:
    """Assert the style; returns the --json summary."""
    lines = stdout.strip().splitlines()
    assert lines[0].startswith(f"{name}: ") and " in " in lines[0], lines
    figures = [n for n in lines if n.startswith("figures: ")]
    report = [n for n in lines if n.startswith("report: ")]
    assert len(report) == 1 and len(figures) == 1, lines
    body = lines[1:lines.index(report[0])]
    assert body and all(n.startswith("  ") and "|" not in n for n in body), body
    assert lines.index(figures[0]) == len(lines) - 2   # then the JSON
    summary = json.loads(lines[-1])
    report_path = summary.get("table") or summary["report"]
    assert report[0] == f"report: {report_path}" and Path(report_path).parent == out
    names = [Path(p).name for p in summary.get("plots") or summary["figures"]]
    assert names and figures[0] == f"figures: {', '.join(names)} (in {out})"
    return summary
