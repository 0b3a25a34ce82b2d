"""The firmware's servo-bus masters side by side, one a Dynamixel protocol: v1.py (the
AX-12's Protocol 1.0), v2.py (the X series' Protocol 2.0), picked by the version the hello's
config names (protocol/link_schema.py PROTOCOL, which the host takes from the model's entry
in protocol/dynamixel/models.py). Both keep one interface (scan, configure, SYNC_WRITE of
the goals, status reads, counters), so the controller and the fault policy use either.
Each loads only when picked: the board's small flash filesystem and heap carry the one it
drives (docs/micropython-on-the-chip.md). MicroPython-compatible.
"""
def master_class(protocol):
    """The master class for Dynamixel protocol ``protocol`` (1 or 2), imported on demand."""
    if protocol == 1:
        from firmware.servo_bus.v1 import Master
        return Master
    if protocol == 2:
        from firmware.servo_bus.v2 import Master2
        return Master2
    raise ValueError("no servo-bus master for protocol %r" % (protocol,))
