"""The bus fuzzer (``hexhil fuzz``, docs/fuzzing.md): faults placed in virtual time on the
servo bus, the switches, the CAN bus and the supply, run against a firmware from a state
saved after boot, judged by an expectation file, each failure shrunk to a scenario that
replays it. mutations.py draws and changes the faults, execution.py runs them (a fork
server in process, a fresh run otherwise), campaign.py guides, judges and shrinks."""
