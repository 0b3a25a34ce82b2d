"""Benchmarks (``make bench``): each ``bench_*.py`` returns rows for one printed table."""
from dataclasses import dataclass


@dataclass
class Row:
    name: str
    value: float
    unit: str
    target: str = ""
    note: str = ""
