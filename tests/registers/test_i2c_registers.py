"""I2C1 (hil/mcu/devices/i2c.py) through the bus, as HAL_I2C_IsDeviceReady drives it on a
bus with no device: START gives SB, MSL and BUSY a SCL period later, the address is not
acknowledged (AF after nine periods), STOP frees the bus."""
from registers.bus import Bus

APB1ENR = 0x40023840
I2C1 = 0x40005400
CR1, CR2, DR, SR1, SR2, CCR = (I2C1 + o for o in (0x00, 0x04, 0x10, 0x14, 0x18, 0x1C))
SB, AF, MSL, BUSY = 1, 1 << 10, 1, 1 << 1


def test_an_address_nobody_answers_is_a_nack_and_stop_frees_the_bus():
    bus = Bus()
    bus.write(APB1ENR, 1 << 21)
    bus.write(CR2, 16)                          # PCLK1 16 MHz
    bus.write(CCR, 80)                          # 100 kHz: a period of 2 x 80 / 16 MHz = 10 us
    bus.write(CR1, 1)                           # PE
    bus.write(CR1, 1 | 1 << 8)                  # START
    assert bus.read(SR1) & SB == 0
    bus.advance(11e-6)
    assert (bus.read(SR1) & SB, bus.read(SR2) & (MSL | BUSY)) == (SB, MSL | BUSY)
    bus.write(DR, 0x68 << 1)                    # an IMU's address, write
    bus.advance(85e-6)
    assert bus.read(SR1) & AF == 0              # nine periods: 90 us
    bus.advance(10e-6)
    assert bus.read(SR1) & (AF | SB) == AF
    bus.write(CR1, 1 | 1 << 9)                  # STOP
    bus.write(SR1, ~AF & 0xFFFF)                # AF is rc_w0
    bus.advance(11e-6)
    assert (bus.read(SR1) & AF, bus.read(SR2) & BUSY, bus.read(CR1) & (1 << 9)) == (0, 0, 0)
