"""``make fuzz``: hostile inputs for every parser and loader hexhil has.

Each ``fuzz/fuzz_*.py`` module exposes ``run(seed, budget_s, limit) -> Tally``; ``make
fuzz`` runs them all for a time budget and prints one table, ``tests/test_fuzz.py`` runs a
short seeded slice of each so a regression fails ``make test``.
"""
