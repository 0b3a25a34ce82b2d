"""The chip's identity (hil/mcu/device_id.py) as firmware reads it: the unique ID, the flash
size, the erased OTP area, DBGMCU's IDCODE (HAL_GetUIDw0..2, FLASHSIZE_BASE, HAL_GetDEVID)."""
from registers.bus import Bus


def test_unique_id_flash_size_otp_and_idcode():
    bus = Bus()
    uid = [bus.read(0x1FFF7A10 + 4 * i) for i in range(3)]
    assert uid == [0x00470031, 0x4C48580D, 0x31484558]       # fixed: the same every run
    assert bus.read(0x1FFF7A22, 2) == 512                    # KB of flash
    assert bus.read(0x1FFF7800) == 0xFFFFFFFF                # OTP, erased
    idcode = bus.read(0xE0042000)
    assert (idcode & 0xFFF, idcode >> 16) == (0x431, 0x1000)  # STM32F411xC/E, revision A
