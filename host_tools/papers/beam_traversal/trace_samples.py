"""The force samples of a recorded run, for the beam estimator (``hexhil estimate``): any
trace with ``force`` and ``body_pose`` CAN frames on /can/raw, simulated (``hexhil beams run
--out``) or a physical robot's CSV brought in by ``hexhil trace import-csv``. Each force
sample is paired with the body pose logged at the same instant or, failing that, the latest
one before it."""
from __future__ import annotations

import numpy as np

from hexhil.trace.protobuf import CanFrame
from hexhil.trace.reader import Trace
from hexhil.trace.topics import T_CAN_RAW
from hexhil.protocol import can_frames
from hexhil.protocol.errors import BadValue


def load_samples(path: str, start_s: float | None, end_s: float | None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict | None]:
    """(t_s, poses [x_m, roll_rad, pitch_rad], forces [N]) and the last logged estimate."""
    cls = CanFrame
    t, poses, forces = [], [], []
    pose = None
    logged = None
    held: list[tuple[float, tuple[float, float, float]]] = []  # forces at the current time
    held_ns = -1

    def release() -> None:
        if pose is not None:
            for ts, f in held:
                t.append(ts)
                poses.append(pose)
                forces.append(f)
        held.clear()

    with Trace(path) as tr:
        if T_CAN_RAW not in tr.topics():
            raise BadValue(f"{path}: no {T_CAN_RAW} topic, so no force frames to estimate from")
        for m in tr.messages([T_CAN_RAW], start_s, end_s):
            if m.log_time_ns != held_ns:
                release()  # a pose logged at the same instant as a force belongs to it
                held_ns = m.log_time_ns
            f = cls.FromString(m.data)
            if f.is_extended_id or f.arbitration_id not in can_frames.BY_ID:
                continue
            try:
                name, sig = can_frames.decode(f.arbitration_id, f.data)
                if name == "beam_estimate" and sig["mode"] >= len(can_frames.MODE_NAMES):
                    raise ValueError(f"beam_estimate.mode {sig['mode']} is not a mode")
            except ValueError as exc:
                raise BadValue(f"{path}: bad CAN frame at t={m.log_time_ns / 1e9:.6f} s "
                               f"({exc})") from None
            if name == "body_pose":
                pose = (sig["x_m"], sig["roll_rad"], sig["pitch_rad"])
            elif name == "force":
                held.append((m.log_time_ns / 1e9, (sig["fx_n"], sig["fy_n"], sig["fz_n"])))
            elif name == "beam_estimate":
                logged = {"k1": sig["k1_nm_per_rad"], "k2": sig["k2_nm_per_rad"],
                          "hb_mm": sig["hb_m"] * 1e3,
                          "mode": can_frames.MODE_NAMES[sig["mode"]]}
        release()
    if not forces:
        raise BadValue(f"{path}: no force frames with a body pose before them "
                       "(the estimator needs both 'force' and 'body_pose' frames)")
    return np.array(t), np.array(poses), np.array(forces), logged
