"""The limit-switch sensor node on the servo line (an AX-S1-like Protocol 1.0 device): the
addresses its master reads and the emulated node serves (hil/servobus/switch_node.py has the whole
table; firmware/sensor_switches.py reads it). MicroPython-compatible.
"""
DEFAULT_ID = 100           # the AX-S1's factory ID
MODEL_NUMBER = 0x5348      # "HS": hexhil switches
SWITCHES = 26              # bit i = leg i's switch pressed (protocol/hexapod.py leg order)
PRESSES = 27               # rising edges seen by reads, modulo 256
