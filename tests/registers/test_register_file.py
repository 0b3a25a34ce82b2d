"""The generic register file (hil/mcu/registers.py): each access rule of RM0383 applied by
the description alone, and the names an access without behaviour is logged by."""
import logging

from hexhil.hil.mcu.registers import Description, RegisterFile, reg

DEV = Description("DEV", (
    reg("CTRL", 0x00, 0x0000_00A5, "EN:0:rw MODE:4-7:rw RO:8:r KEY:16-23:w"),
    reg("FLAGS", 0x04, 0x0000_00FF, "A:0:rc_w1 B:1:rc_w0 C:2:rc_r T:3:t S:4:rs HW:5-7:r"),
))


def test_reset_values_and_reserved_bits():
    f = RegisterFile(DEV)
    assert f.read(0x00) == 0xA5            # KEY (write-only) reads 0
    f.write(0x00, 0xFFFF_FFFF)
    # EN and MODE take the value, RO and the reserved bits (2 was set) keep theirs,
    # KEY reads 0
    assert f.read(0x00) == 0x0000_00F5


def test_read_only_bits_keep_their_value():
    f = RegisterFile(DEV)
    f.set_bits("CTRL", 1 << 8)             # the hardware sets RO
    f.write(0x00, 0)
    assert f.read(0x00) >> 8 & 1 == 1


def test_write_one_to_clear_and_write_zero_to_clear():
    f = RegisterFile(DEV)
    f.write(0x04, 0b10)                    # A: 0 written keeps it; B: 1 written keeps it
    assert f.read(0x04) & 0b11 == 0b11
    f.write(0x04, 0b01)                    # A cleared by its 1, B cleared by its 0
    assert f.read(0x04) & 0b11 == 0


def test_cleared_by_read_toggle_and_set_only():
    f = RegisterFile(DEV)
    assert f.read(0x04) >> 2 & 1 == 1      # C reads 1 once ...
    assert f.read(0x04) >> 2 & 1 == 0      # ... then 0
    f.write(0x04, 0b1000 | 0b11)           # T toggles to 0 (it was 1)
    assert f.read(0x04) >> 3 & 1 == 0
    f.write(0x04, 0b1000 | 0b11)
    assert f.read(0x04) >> 3 & 1 == 1
    f.write(0x04, 0b11)                    # S (rs) is not cleared by a 0
    assert f.read(0x04) >> 4 & 1 == 1
    assert f.read(0x04) >> 5 == 0b111      # HW (r) untouched by every write


def test_behaviour_attached_by_name_hears_the_written_value():
    f = RegisterFile(DEV)
    heard = []
    f.behave("CTRL", write=lambda old, new: heard.append((old, new)))
    f.write(0x00, 0x0012_3401)
    assert heard == [(0xA5, 0x0012_0005)]
    assert f.read(0x00) & 0xFF_0000 == 0      # KEY reached the behaviour, reads 0


def test_an_access_without_behaviour_is_named_once(caplog):
    noted: set[str] = set()
    f = RegisterFile(DEV, noted)
    with caplog.at_level(logging.WARNING):
        f.read(0x04)
        f.write(0x04, 0)
        f.read(0x40)
        f.write(0x40, 1)
        RegisterFile(DEV, noted).read(0x04)     # after a system reset: the same run
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 2, messages
    assert messages[0].startswith("firmware used DEV.FLAGS, a register without behaviour")
    assert messages[1].startswith("firmware used DEV+0x040, where DEV has no register")
    assert "0x4" not in messages[0]
    assert f.read(0x40) == 0
