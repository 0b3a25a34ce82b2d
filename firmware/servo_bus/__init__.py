"""The firmware's servo-bus masters side by side, one a Dynamixel protocol: v1.py (the
AX-12's Protocol 1.0), v2.py (the X series' Protocol 2.0), keyed by the version the hello's
config names (protocol/link_schema.py PROTOCOL, which the host takes from the model's entry
in protocol/dynamixel/models.py). Both keep one interface (scan, configure, SYNC_WRITE of
the goals, status reads, counters), so the controller and the fault policy use either.
MicroPython-compatible.
"""
from firmware.servo_bus import v1, v2

MASTERS = {1: v1.Master, 2: v2.Master2}
