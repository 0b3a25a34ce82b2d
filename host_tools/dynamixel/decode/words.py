"""A decoded packet (the record of v1.py's or v2.py's ``describe``) in one line of words, its
parameters read against a servo model's control table (protocol/dynamixel/models.py): what a
replay divergence names, e.g. ``WRITE id 3 Goal Position (30) = 512``,
``SYNC_WRITE Goal Position+Moving Speed ids 1-18 [1: 512,100; ...]``,
``READ id 5 Present Position (36) 2 bytes``, ``status id 5 ok: Present Position (36) = 512``."""
from __future__ import annotations

from types import ModuleType
from typing import Any, Sequence


def _name(field: tuple) -> str:
    return field[1].replace("_", " ").title()


def _fields(table: ModuleType, address: int, length: int) -> list[tuple] | None:
    """The fields that ``length`` bytes from ``address`` fill exactly, or None."""
    out, a = [], address
    while a < address + length:
        f = table.BY_ADDRESS.get(a)
        if f is None or a + f[2] > address + length:
            return None
        out.append(f)
        a += f[2]
    return out


def _value(field: tuple, data: Sequence[int]) -> int:
    # a table whose rows end in a ``signed`` flag (X series) says which fields are signed
    return int.from_bytes(bytes(data), "little", signed=field[-1] is True)


def _hex(data: Sequence[int]) -> str:
    return " ".join(f"{b:02X}" for b in data)


def values(table: ModuleType, address: int, data: Sequence[int]) -> str:
    """``data`` written or read at ``address``: each field it fills with its value
    (``Goal Position (30) = 512, Moving Speed (32) = 100``), else the address and bytes."""
    fields = _fields(table, address, len(data))
    if not fields:
        return f"address {address} = {_hex(data) or 'nothing'}"
    out, at = [], 0
    for f in fields:
        out.append(f"{_name(f)} ({f[0]}) = {_value(f, data[at:at + f[2]])}")
        at += f[2]
    return ", ".join(out)


def span(table: ModuleType, address: int, length: int) -> str:
    """What a read of ``length`` bytes at ``address`` asks for: ``Present Position (36)
    2 bytes``."""
    fields = _fields(table, address, length)
    what = ("+".join(_name(f) for f in fields) + f" ({address})" if fields
            else f"address {address}")
    return f"{what} {length} byte{'s' if length != 1 else ''}"


def ids(numbers: Sequence[int]) -> str:
    """``1-18``, ``1,3,5``, ``1-3,7``."""
    runs: list[list[int]] = []
    for n in numbers:
        if runs and n == runs[-1][1] + 1:
            runs[-1][1] = n
        else:
            runs.append([n, n])
    return ",".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs)


def _entries(table: ModuleType, address: int, length: int,
             entries: list[dict[str, Any]]) -> str:
    fields = _fields(table, address, length)
    head = "+".join(_name(f) for f in fields) if fields else f"address {address} {length} bytes"
    rows = []
    for e in entries:
        if fields:
            at, vals = 0, []
            for f in fields:
                vals.append(str(_value(f, e["data"][at:at + f[2]])))
                at += f[2]
            rows.append(f"{e['id']}: {','.join(vals)}")
        else:
            rows.append(f"{e['id']}: {_hex(e['data'])}")
    return f"{head} ids {ids([e['id'] for e in entries])} [{'; '.join(rows)}]"


def phrase(rec: dict[str, Any], table: ModuleType) -> str:
    """One decoded packet record in words, its parameters against ``table``."""
    if rec["kind"] == "status":
        head = f"status id {rec['id']} {','.join(rec['error']) or 'ok'}"
        data = rec.get("params", [])
        if not data:
            return head
        if rec.get("address") is not None:
            return f"{head}: {values(table, rec['address'], data)}"
        return f"{head}: data {_hex(data)}"
    name = rec["instruction"]
    if "entries" in rec and "address" in rec:             # SYNC_WRITE
        return f"{name} {_entries(table, rec['address'], rec['length'], rec['entries'])}"
    if "entries" in rec:                                  # BULK_READ, BULK_WRITE
        parts = [f"id {e['id']} " + (values(table, e["address"], e["data"]) if "data" in e
                                     else span(table, e["address"], e["length"]))
                 for e in rec["entries"]]
        return f"{name} " + "; ".join(parts)
    if "length" in rec:                                   # READ, SYNC_READ
        what = span(table, rec["address"], rec["length"])
        if "ids" in rec:
            return f"{name} {what} ids {ids(rec['ids'])}"
        return f"{name} id {rec['id']} {what}"
    if "data" in rec:                                     # WRITE, REG_WRITE
        return f"{name} id {rec['id']} {values(table, rec['address'], rec['data'])}"
    params = rec.get("params") or []
    return f"{name} id {rec['id']}" + (f" params {_hex(params)}" if params else "")
