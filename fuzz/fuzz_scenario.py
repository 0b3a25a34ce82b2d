"""The TOML scenario loader (hil/scenario.py, and the fault lists hil/servobus/faults.py checks):
random documents and mutated shipped scenarios give a checked dict or a one-line
UserError, never another exception."""
from __future__ import annotations

import json
import math
import random
import tempfile
from pathlib import Path
from typing import Any

from fuzz.tally import Budget, Tally
from hexhil.hil import scenario
from hexhil.hil.servobus.faults import Faults
from hexhil.protocol.errors import UserError

SHIPPED = sorted((Path(__file__).resolve().parent.parent / "scenarios").glob("*.toml"))
ODD_STRINGS = ("", "tripod", "wave", "beams", "hexapod", "original", "\u00e9\u0000", "x" * 300)


def _value(rng: random.Random, want: type | None) -> Any:
    """Mostly the right type with a hostile value, sometimes any type at all."""
    want = want if want is not None and rng.random() < 0.8 else rng.choice(
        (int, float, str, bool, list, dict))
    if want is int:
        return rng.choice((0, -1, 1, 2, 7, 18, 253, 254, 255, 1_000_000, 2**63 - 1, -2**63))
    if want is float:
        return rng.choice((0.0, -0.0, -1.0, 1e-4, 0.5, 1.0, 600.0, 1e308, math.inf, -math.inf,
                           math.nan, rng.uniform(-10, 10)))
    if want is str:
        return rng.choice(ODD_STRINGS)
    if want is bool:
        return rng.random() < 0.5
    if want is list:
        return [{k: _value(rng, t) for k, t in rng.sample(
            (("id", int), ("at_s", float), ("until_s", float), ("volts", float),
             ("temperature_c", float), ("bogus", str)), rng.randrange(4))}
                for _ in range(rng.randrange(3))] if rng.random() < 0.8 else [_value(rng, None)]
    return {"k": 1}


def _toml(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return "{ " + ", ".join(f"{k} = {_toml(x)}" for k, x in v.items()) + " }"


def document(rng: random.Random) -> str:
    """A random scenario: known sections and keys, hostile values, now and then a stranger."""
    lines = []
    for section in rng.sample(sorted(scenario.SCHEMA), rng.randrange(1, 5)):
        lines.append(f"[{section if rng.random() < 0.95 else section + 'x'}]")
        keys = scenario.SCHEMA[section]
        for key in rng.sample(sorted(keys), rng.randrange(len(keys) + 1)):
            lines.append(f"{key} = {_toml(_value(rng, keys[key]))}")
        if rng.random() < 0.05:
            lines.append(f"unknown_key = {_toml(_value(rng, None))}")
    return "\n".join(lines) + "\n"


def mutated(rng: random.Random, texts: list[str]) -> str:
    """A shipped scenario with one character or line changed."""
    text = rng.choice(texts)
    at = rng.randrange(len(text))
    kind = rng.randrange(3)
    if kind == 0:
        return text[:at] + text[at + 1:]
    if kind == 1:
        return text[:at] + rng.choice("=[]{}\"'#.,0123456789-e\n x") + text[at:]
    lines = text.splitlines()
    i = rng.randrange(len(lines))
    return "\n".join(lines[:i] + [lines[i]] * 2 + lines[i + 1:])


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    rng = random.Random(seed)
    texts = [p.read_text(encoding="utf-8") for p in SHIPPED]
    tally = Tally("TOML scenario loader", "documents")
    budget = Budget(budget_s, limit)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.toml"
        while budget.more(tally.inputs):
            tally.inputs += 1
            text = document(rng) if rng.random() < 0.6 else mutated(rng, texts)
            path.write_text(text, encoding="utf-8")
            try:
                sc = scenario.load_scenario(path)
                Faults(sc.faults, sc.scenario.seed)
                tally.notes["accepted"] = tally.notes.get("accepted", 0) + 1
            except UserError as exc:
                if "\n" in str(exc):
                    tally.escape(f"UserError over several lines: {exc!r}")
            except Exception as exc:  # an escape is what the fuzzer is for
                tally.escape(f"{exc.__class__.__name__}: {exc} <- {text!r}")
    tally.wall_s = budget.elapsed_s()
    return [tally]
