# protocol/sensor_node.py under the real micropython binary: the switch read the firmware
# sends to the node (firmware/sensor_switches.py) is the AX-S1-like READ of byte 26 at ID 100.
from protocol.dynamixel import v1 as dxl
from protocol import sensor_node
from tests.micropython.checks import check, done

check(sensor_node.DEFAULT_ID == 100 and sensor_node.SWITCHES == 26, "factory ID, Switches")
check(sensor_node.PRESSES == sensor_node.SWITCHES + 1, "Presses follows Switches")
check(dxl.read(sensor_node.DEFAULT_ID, sensor_node.SWITCHES, 1)
      == bytes((0xFF, 0xFF, 0x64, 0x04, 0x02, 0x1A, 0x01, 0x7A)), "the switch read's bytes")
done("sensor_node")
