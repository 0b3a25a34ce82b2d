"""firmware/servo_bus/v2.py (the X-series master) against the emulated Protocol 2.0 bus:
scan, configuration, one SYNC_WRITE, one SYNC_READ of all 18, stuffed replies, a silent
servo ending the chain; the return delay both masters write at configuration."""
from __future__ import annotations

from hexhil.firmware.servo_bus import v2 as servo_bus2
from hexhil.hil.servobus.protocols.v2 import Bus2
from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus.xseries_servo import XSeriesServo
from hexhil.protocol.dynamixel import xl430 as xl


class BusUart:
    """The firmware's UART and clock seams over a lockstep Bus2."""

    def __init__(self, bus: Bus2) -> None:
        self.bus = bus

    def write(self, buf: bytearray, n: int) -> None:
        self.bus.master_write(bytes(buf[:n]))

    def transact(self, buf: bytearray, n: int, rx: bytearray, nrx: int, timeout_us: int) -> int:
        if n:
            self.bus.master_write(bytes(buf[:n]))
        data = self.bus.master_read(nrx, timeout_us)
        rx[:len(data)] = data
        return len(data)

    def ticks_us(self) -> int:
        return self.bus.clock.t_us

    def ticks_add(self, a: int, b: int) -> int:
        return a + b

    def sleep_until(self, t_us: int) -> None:
        self.bus.idle_until(t_us)


class Stuffed(XSeriesServo):
    """Present Load -1 and Present Velocity -3: FF FF FD FF ... on the wire (stuffed)."""

    def read_block(self, address: int, length: int) -> tuple[int, bytes]:
        error, data = super().read_block(address, length)
        if address == xl.PRESENT_LOAD and length >= 3:
            data = b"\xff\xff\xfd" + data[3:]
        return error, data


def rig(stuffed: int = 0) -> tuple[Bus2, servo_bus2.Master2, BusUart]:
    servos = [(Stuffed if i == stuffed else XSeriesServo)(i) for i in range(1, 19)]
    for s in servos:
        s.table[xl.BAUD_RATE] = 3
    bus = Bus2(servos, VirtualClock())
    uart = BusUart(bus)
    return bus, servo_bus2.Master2(uart, list(range(1, 19))), uart


def test_scan_configure_write_and_one_sync_read_of_all_18() -> None:
    bus, m, now = rig()
    assert m.scan(now) == list(range(1, 19))
    for i in range(1, 19):           # as the controller does: EEPROM, settle, then RAM
        assert m.configure_eeprom(i, 200, 800, now)
    now.sleep_until(now.ticks_us() + servo_bus2.EEPROM_SETTLE_US)
    for i in range(1, 19):
        assert m.configure_ram(i, 1, 32, now)
    m.return_delay_us = 0
    assert bus.servos[0].value("return_delay_time") == 0
    assert bus.servos[0].value("max_position_limit") == servo_bus2.ax_to_pulses(800)
    m.sync_write([600] * 18, [100] * 18, now)
    bus.idle_until(bus.clock.t_us + 1_000_000)
    tx_before = bus.stats["packets"]
    assert m.sync_read_present(now) == []
    assert bus.stats["packets"] == tx_before + 1                  # ONE instruction
    assert all(abs(m.servos[i].position - 600) <= 1 for i in range(1, 19))
    assert m.read_present(5, now) and abs(m.servos[5].position - 600) <= 1


def test_a_stuffed_reply_is_read_to_its_end() -> None:
    bus, m, now = rig(stuffed=18)
    m.scan(now)
    assert m.sync_read_present(now) == []                         # the last one was stuffed
    assert m.servos[18].load == 0xFFFF and m.sync_reads == 1


def test_a_silent_servo_ends_the_chain() -> None:
    bus, m, now = rig()
    m.scan(now)
    bus.set_plugged(bus.servos[4], False, bus.clock.t_us)
    assert m.sync_read_present(now) == list(range(4, 18))
    assert m.servos[5].timeouts == 1 and m.servos[4].timeouts == 0


def test_configuration_writes_the_return_delay_the_board_asks_for() -> None:
    """delay_set_us (the board back end's 100 us: hal/board.py) reaches every servo's
    register in both protocols, in its 2 us units."""
    from hexhil.firmware.servo_bus import master_class
    from hexhil.hil.servobus.ax12_servo import Servo
    from hexhil.hil.servobus.line import Bus

    bus, m, now = rig()
    m.delay_set_us = 100
    assert m.configure_eeprom(1, 200, 800, now)
    assert bus.servos[0].value("return_delay_time") == 50
    assert bus.servos[0].return_delay_us == 100
    bus1 = Bus([Servo(i) for i in range(1, 19)], VirtualClock())
    m1 = master_class(1)(BusUart(bus1), list(range(1, 19)))
    m1.delay_set_us = 100
    assert m1.configure_eeprom(2, 200, 800, BusUart(bus1))
    assert bus1.servos[1].return_delay_us == 100
