"""A CAN frame's signals as the trace holds them on ``/can/<frame name>``: the DBC's
decoding (protocol/hexhil.dbc through cantools; our own frames through
protocol/can_frames.py, which tests/test_can_frames.py holds to the DBC for every frame,
~10x faster than cantools), each topic's JSON schema, and the JSON the recorder writes."""
from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

from hexhil.trace.topics import CAN_SCHEMA_PREFIX
from hexhil.protocol import can_frames


@functools.cache
def dbc():
    """The project's DBC through cantools (loaded once a process: ~13 ms, as much as
    recording 10 s of a run), or None while protocol/hexhil.dbc is absent."""
    path = Path(can_frames.__file__).with_name("hexhil.dbc")
    if not path.exists():
        return None
    import cantools

    return cantools.database.load_file(str(path))


@functools.cache
def json_schema(msg: Any) -> str:
    """The JSON schema of one DBC frame's decoded signals, units in the descriptions."""
    props = {s.name: {"type": "number", "description": f"{s.comment or s.name} [{s.unit or '-'}]"}
             for s in msg.signals}
    props["direction"] = {"type": "string"}
    return json.dumps({"title": CAN_SCHEMA_PREFIX + msg.name, "type": "object",
                       "properties": props}, sort_keys=True)


def to_json(values: Any) -> str:
    return _JSON_ENCODER.encode(values)


def json_default(o: Any) -> Any:
    if isinstance(o, (bytes, bytearray)):
        return o.hex()
    if hasattr(o, "tolist"):  # numpy scalars and arrays
        return o.tolist()
    if hasattr(o, "value"):  # cantools NamedSignalValue
        return o.value
    return str(o)


# one encoder for the run (json.dumps with default= builds a new one per call)
_JSON_ENCODER = json.JSONEncoder(default=json_default)


class CanSignals:
    """Each frame ID's DBC message, looked up once; ``decode`` gives a frame's signals."""

    def __init__(self, decode: bool = True) -> None:
        self._dbc = dbc() if decode else None
        self._kinds: dict[tuple[int, bool], tuple[str, Any, bool]] = {}

    def decode(self, arb_id: int, data: bytes, is_extended_id: bool = False
               ) -> tuple[str, Any, dict[str, Any] | None]:
        """(DBC name or "", the DBC message or None, its signals in SI units or None when
        the DBC does not know the frame or cannot decode it)."""
        kind = self._kinds.get((arb_id, is_extended_id))
        if kind is None:
            kind = self._kinds[(arb_id, is_extended_id)] = self._kind(arb_id, is_extended_id)
        name, msg, ours = kind
        if msg is None:
            return name, None, None
        try:
            signals = (can_frames.decode(arb_id, data)[1] if ours
                       else msg.decode(data, decode_choices=False))
        except Exception:  # a frame the DBC cannot decode stays raw only
            return name, msg, None
        return name, msg, signals

    def _kind(self, arb_id: int, is_extended_id: bool) -> tuple[str, Any, bool]:
        """(DBC name or "", the DBC message or None, whether protocol/can_frames knows it)."""
        if self._dbc is None or is_extended_id:
            return "", None, False
        try:
            msg = self._dbc.get_message_by_frame_id(arb_id)
        except KeyError:
            return "", None, False
        return msg.name, msg, can_frames.BY_ID.get(arb_id) == msg.name
