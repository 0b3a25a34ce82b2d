"""A physical robot's CSV log -> an MCAP trace (``hexhil trace import-csv``), seed 000
Sec. IV: force at 100 Hz, the tracked body pose interpolated to the force samples."""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

from hexhil.trace.reader import why
from hexhil.trace.recorder import Recorder
from hexhil.protocol import can_frames
from hexhil.protocol.errors import BadFile, BadValue, UserError

CSV_REQUIRED = ("time_s", "fx_n", "fy_n", "fz_n")
CSV_POSE = ("x_m", "roll_rad", "pitch_rad")
CSV_OPTIONAL = ("y_m", "z_m")


def _quat_wxyz(roll_rad: float, pitch_rad: float, yaw_rad: float = 0.0) -> tuple[float, ...]:
    """Roll, pitch, yaw (Z-Y-X Euler angles) -> the unit quaternion (w, x, y, z)."""
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def import_csv(src: str | Path, dst: str | Path, metadata: dict[str, Any] | None = None,
               overwrite: bool = False) -> dict[str, Any]:
    """A physical robot's CSV (``time_s, fx_n, fy_n, fz_n`` and, for the estimator, the
    body pose ``x_m, roll_rad, pitch_rad``; optional ``y_m, z_m``) -> an MCAP trace with the
    same ``force`` and ``body_pose`` CAN frames a simulated beams run records."""
    src = Path(src)
    if src.exists() and not src.is_file() and not src.is_dir():
        raise BadFile(f"{src}: not a regular file (a CSV log is a file)")
    try:
        f = open(src, newline="", encoding="utf-8")
    except FileNotFoundError:
        raise BadFile(f"{src}: no such CSV file") from None
    except OSError as exc:
        raise BadFile(f"{src}: cannot read ({exc.strerror})") from None
    with f:
        try:
            reader = csv.DictReader(f)
            header = [h.strip() for h in (reader.fieldnames or [])]
        except (csv.Error, UnicodeDecodeError) as exc:
            raise BadValue(f"{src}: not a readable CSV ({why(exc)})") from None
        missing = [c for c in CSV_REQUIRED if c not in header]
        if missing:
            raise BadValue(f"{src}: CSV lacks column(s) {', '.join(missing)} "
                           f"(needs {', '.join(CSV_REQUIRED + CSV_POSE)})")
        has_pose = all(c in header for c in CSV_POSE)
        ignored = [h for h in header if h not in CSV_REQUIRED + CSV_POSE + CSV_OPTIONAL]
        reader.fieldnames = header
        meta = {"source": "import-csv", "csv": src.name}
        meta.update(metadata or {})
        out = Recorder(dst, meta, overwrite=overwrite)
        n = 0
        last_us = -1
        try:
            for line, row in enumerate(reader, start=2):
                try:
                    vals = {k: float(row[k]) for k in header
                            if k not in ignored and row[k] not in (None, "")}
                    t_us = int(round(vals["time_s"] * 1e6))
                    fx, fy, fz = vals["fx_n"], vals["fy_n"], vals["fz_n"]
                except (KeyError, ValueError, TypeError):
                    raise BadValue(f"{src}:{line}: needs numbers in "
                                   f"{', '.join(CSV_REQUIRED)}") from None
                if t_us < 0 or t_us < last_us:
                    raise BadValue(f"{src}:{line}: time_s must be >= 0 and non-decreasing")
                if not all(math.isfinite(v) for v in vals.values()):
                    raise BadValue(f"{src}:{line}: non-finite value")
                last_us = t_us
                arb, data = can_frames.encode("force", fx_n=fx, fy_n=fy, fz_n=fz,
                                              sample=n)
                out.can(t_us, arb, data, direction="rx")
                if has_pose and all(k in vals for k in CSV_POSE):
                    arb, data = can_frames.encode("body_pose", x_m=vals["x_m"],
                                                  roll_rad=vals["roll_rad"],
                                                  pitch_rad=vals["pitch_rad"])
                    out.can(t_us, arb, data, direction="rx")
                    out.body_pose(t_us, (vals["x_m"], vals.get("y_m", 0.0),
                                         vals.get("z_m", 0.0)),
                                  _quat_wxyz(vals["roll_rad"], vals["pitch_rad"]))
                n += 1
            if n == 0:
                raise BadValue(f"{src}: CSV has no data rows")
        except csv.Error as exc:
            out.discard()
            raise BadValue(f"{src}: malformed CSV ({why(exc)})") from None
        except UserError:
            out.discard()
            raise
        out.close()
    return {"input": str(src), "output": str(dst), "samples": n, "pose": has_pose,
            "ignored_columns": ignored}
