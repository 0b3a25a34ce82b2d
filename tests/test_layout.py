"""docs/foxglove-layout.json names only topics (and fields) a recorded hexapod run writes."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from host_tools.trace.reader import open_trace

ROOT = Path(__file__).resolve().parent.parent
HEXHIL = str(Path(sys.executable).with_name("hexhil"))


def _named_topics(layout: dict) -> set[str]:
    """Every topic a panel reads: 3D topics, message paths' topics, raw-message topics."""
    found = set()
    for key, cfg in layout["configById"].items():
        found |= set(cfg.get("topics", {}))
        paths = [p["value"] for p in cfg.get("paths", [])]
        paths += [cfg["topicPath"]] if cfg.get("topicPath") else []
        for path in paths:
            found.add(re.match(r"(/[\w/]+)", path).group(1).rstrip("/"))
    return found


def test_layout_topics_are_written_by_a_run(tmp_path):
    layout = json.loads((ROOT / "docs/foxglove-layout.json").read_text())
    out = tmp_path / "run.mcap"
    r = subprocess.run([HEXHIL, "run", "scenarios/obstacles-high-large.toml", "--duration", "2",
                        "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    with open_trace(out) as tr:
        written = {m.topic for m in tr.messages()}
        fields = {m.topic: set(json.loads(m.data)) for m in tr.messages(["/can/*"])
                  if m.topic != "/can/raw"}
    named = _named_topics(layout)
    assert {"/scene", "/scene/forces", "/joints", "/servos", "/can/tactile"} <= named
    assert named <= written, named - written
    # the decoded CAN signals the panels plot exist in the frames
    for cfg in layout["configById"].values():
        for path in [p["value"] for p in cfg.get("paths", [])]:
            topic, _, field = path.partition(".")
            if topic in fields:
                assert field in fields[topic], path
    three_d = layout["configById"]["3D!robot"]
    assert three_d["followTf"] == "body"
