"""Trace -> CSV (one wide table per topic) or a python-can CAN log of ``/can/raw``."""
from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, Iterable

from hexhil.hil.scenario import check_span
from hexhil.trace.protobuf import CanFrame
from hexhil.trace.reader import Trace, why
from hexhil.trace.topics import T_CAN_RAW
from hexhil.protocol.errors import BadFile, BadValue, UserError

CAN_LOG_SUFFIXES = (".asc", ".blf", ".log", ".trc")


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else k, v, out)
    elif isinstance(value, list) and value and isinstance(value[0], dict):
        for i, v in enumerate(value):
            _flatten(f"{prefix}[{i}]", v, out)
    elif isinstance(value, list):
        out[prefix] = " ".join(str(x) for x in value)
    else:
        out[prefix] = value


def export(path: str | Path, out: str | Path, topics: Iterable[str] | None = None,
           start_s: float | None = None, end_s: float | None = None) -> dict[str, Any]:
    """CSV (one wide table per topic) or, by suffix, a python-can CAN log of /can/raw."""
    check_span(start_s, end_s)
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix in CAN_LOG_SUFFIXES:
        return _export_can(path, out, start_s, end_s)
    if suffix != ".csv" and out.suffix:
        raise BadValue(f"{out}: unknown export format '{out.suffix}' "
                       f"(use .csv or one of {', '.join(CAN_LOG_SUFFIXES)})")
    if suffix == ".csv" and not out.parent.is_dir():
        raise BadFile(f"{out}: folder {out.parent} does not exist (create it, or export elsewhere)")
    with Trace(path) as tr:
        chosen = tr.select_topics(topics) or tr.topics()
        if suffix == ".csv" and len(chosen) > 1:
            raise UserError(f"{out}: a .csv file holds one topic and {len(chosen)} match "
                            f"({', '.join(chosen)}): pick one with topics, or give a folder "
                            f"name without .csv for one CSV per topic", params=("topics",))
        rows: dict[str, list[dict[str, Any]]] = {}
        for m, value in tr.decoded(topics, start_s, end_s):
            flat: dict[str, Any] = {"time_s": f"{m.log_time_ns / 1e9:.6f}"}
            _flatten("", value, flat)
            rows.setdefault(m.topic, []).append(flat)
    files = []
    if suffix == ".csv":
        targets = {t: out for t in rows}
        if not rows:
            try:
                out.write_text("time_s\n")
            except OSError as exc:
                raise BadFile(f"{out}: cannot write ({exc.strerror})") from None
            files.append(str(out))
    else:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise BadFile(f"{out}: cannot create export directory ({exc.strerror})") from None
        targets = {t: out / (t.strip("/").replace("/", "_") + ".csv") for t in rows}
    for topic, target in targets.items():
        cols: dict[str, None] = {}
        for r in rows[topic]:
            for k in r:
                cols.setdefault(k, None)
        try:
            with open(target, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(cols))
                w.writeheader()
                w.writerows(rows[topic])
        except OSError as exc:
            raise BadFile(f"{target}: cannot write ({exc.strerror})") from None
        files.append(str(target))
    return {"format": "csv", "files": files,
            "messages": sum(len(v) for v in rows.values()), "topics": sorted(rows)}


def _export_can(path: str | Path, out: Path, start_s: float | None,
                end_s: float | None) -> dict[str, Any]:
    import can

    with Trace(path) as tr:
        if T_CAN_RAW not in tr.topics():
            raise BadValue(f"{tr.path}: no CAN frames to export (no {T_CAN_RAW} topic)")
        cls = CanFrame
        n = 0
        try:
            logger = can.Logger(str(out))
        except (OSError, ValueError) as exc:
            raise BadFile(f"{out}: cannot write CAN log ({why(exc)})") from None
        with logger:
            for m in tr.messages([T_CAN_RAW], start_s, end_s):
                f = cls.FromString(m.data)
                logger.on_message_received(can.Message(
                    timestamp=m.log_time_ns / 1e9, arbitration_id=f.arbitration_id,
                    is_extended_id=f.is_extended_id, data=f.data, dlc=len(f.data),
                    is_rx=f.direction != "tx", channel=0))
                n += 1
    return {"format": out.suffix.lower().lstrip("."), "files": [str(out)], "messages": n,
            "topics": [T_CAN_RAW]}
