"""SCB's fault registers (hil/mcu/faults.py FaultStatus) through the bus: reset values,
SHCSR's enables, CFSR and HFSR written 1 to clear, MMFAR and BFAR as latches; SCR's sleep bits."""
import logging

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


def test_scr_keeps_its_sleep_bits_and_deep_sleep_is_named_once(caplog):
    """HAL_PWR_EnterSTOPMode sets SLEEPDEEP, sleeps, and clears it again by read-modify-write:
    the bits read back as written; Stop mode itself is not modelled, and the log says so."""
    SCR = 0xE000ED10
    bus = Bus()
    with caplog.at_level(logging.WARNING):
        bus.write(SCR, 0x16)                       # SLEEPONEXIT, SLEEPDEEP, SEVONPEND
        assert bus.read(SCR) == 0x16
        bus.write(SCR, bus.read(SCR) & ~0x4)
        bus.write(SCR, 0x4)
    assert bus.read(SCR) == 0x4
    named = [r.getMessage() for r in caplog.records if "SLEEPDEEP" in r.getMessage()]
    assert len(named) == 1 and "not modelled" in named[0]
