"""Run ``fuzz.hostile.run_parser`` and print its digest lines: under ``micropython`` (the
firmware's code path) and under CPython, which must print the same lines.

Usage: micropython fuzz/mpy_parser.py SEED COUNT EVERY
"""
import sys

from fuzz.hostile import run_parser

seed, count, every = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
lines = []
tally = run_parser(seed, count, every, lines)
for line in lines:
    print(line)
print("DONE %d %d %d %d %08x" % tally)
