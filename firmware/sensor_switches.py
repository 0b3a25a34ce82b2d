"""The six limit switches read from the sensor node on the servo line (hil/servobus/switch_node.py,
an AX-S1-like node, docs/servo-bus.md): the switch levels of a back end whose switches are
not wired to the controller (hal/serial.py), through a bus master of their own.
MicroPython-compatible.
"""
from firmware.servo_bus import v1 as servo_bus
from protocol import sensor_node


class SensorSwitches:
    """``read(board)`` -> the switch bits, or None when the node did not answer."""

    def __init__(self, uart, baud, sensor_id=None):
        self.sensor_id = sensor_node.DEFAULT_ID if sensor_id is None else sensor_id
        self.master = servo_bus.Master(uart, [self.sensor_id], baud)

    def __call__(self, board):
        if self.master.read(self.sensor_id, sensor_node.SWITCHES, 1, board):
            return self.master.parser.param(0) & 0x3F
        return None


def attach(board):
    """Make ``board`` (hal/serial.py) read its switches from the sensor node."""
    board.switch_reader = SensorSwitches(board.uart, board.baud, board.sensor_id)
    return board
