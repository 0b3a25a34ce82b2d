"""SCB's fault registers (hil/mcu/faults.py FaultStatus) through the bus: reset values,
SHCSR's enables, CFSR and HFSR written 1 to clear, MMFAR and BFAR as latches."""
from registers.bus import Bus

SHCSR, CFSR, HFSR, MMFAR, BFAR = (0xE000ED00 + o for o in (0x24, 0x28, 0x2C, 0x34, 0x38))


def test_fault_registers_reset_and_write():
    bus = Bus()
    assert [bus.read(a) for a in (SHCSR, CFSR, HFSR, MMFAR, BFAR)] == [0, 0, 0, 0, 0]
    bus.write(SHCSR, 0xFFFFFFFF)
    assert bus.read(SHCSR) == 0x70000          # the enables; the active bits are the core's
    status = bus.board.ppb.faults
    status.cfsr, status.hfsr = 0x00018200, 0x40000000
    bus.write(CFSR, 0x00010000)
    bus.write(HFSR, 0)
    assert (bus.read(CFSR), bus.read(HFSR)) == (0x8200, 0x40000000)
    bus.write(HFSR, 0x40000000)
    bus.write(BFAR, 0x60000004)
    assert (bus.read(HFSR), bus.read(BFAR)) == (0, 0x60000004)
