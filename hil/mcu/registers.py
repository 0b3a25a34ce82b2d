"""A peripheral's registers as data (RM0383's register maps) and the generic register file
that applies their access rules.

A description lists each register's offset, reset value and fields, each field with its
access as RM0383 writes it (``Access``). ``RegisterFile`` is the model a description gets
for free: a read gives the register's value (a ``rc_r`` field clears as it is read), a
write changes only what its fields' access lets it change (``r`` bits kept, ``rc_w1`` bits
cleared by a 1, ``rc_w0`` by a 0, ``t`` bits toggled by a 1, ``w`` bits reach the behaviour
and read 0). Behaviour is attached by name: a peripheral's own code subclasses
``RegisterFile`` and sets ``on_read`` / ``on_write`` entries for its registers. A register
no behaviour is attached to is named once a run in the log as ``PERIPHERAL.REGISTER``; an
offset no register covers as ``PERIPHERAL+0xOFF`` (reads 0, writes dropped).
"""
from __future__ import annotations

import enum
import logging
from dataclasses import dataclass
from typing import Callable

log = logging.getLogger(__name__)


class Access(enum.Enum):
    """A field's access (RM0383 1.1's abbreviations)."""
    RW = "rw"          # read and write
    R = "r"            # read only: writes are ignored
    W = "w"            # write only: reads 0
    RC_W1 = "rc_w1"    # read, cleared by writing 1 (writing 0 does nothing)
    RC_W0 = "rc_w0"    # read, cleared by writing 0 (writing 1 does nothing)
    RC_R = "rc_r"      # read, cleared by the read
    T = "t"            # toggled by writing 1
    RS = "rs"          # read, set by writing 1, cleared only by a reset


@dataclass(frozen=True)
class Field:
    name: str
    lsb: int
    width: int
    access: Access

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.lsb


@dataclass(frozen=True)
class Register:
    name: str
    offset: int
    reset: int
    fields: tuple[Field, ...]

    def mask(self, *accesses: Access) -> int:
        """The bits of the fields with one of ``accesses``."""
        return sum(f.mask for f in self.fields if f.access in accesses)

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no field {name}")


def fields(spec: str) -> tuple[Field, ...]:
    """Fields from ``"NAME:BIT:ACCESS NAME:LSB-MSB:ACCESS ..."`` (RM0383's bit numbers)."""
    out = []
    for item in spec.split():
        name, bits, access = item.split(":")
        lo, _, hi = bits.partition("-")
        out.append(Field(name, int(lo), int(hi or lo) - int(lo) + 1, Access(access)))
    return tuple(out)


def reg(name: str, offset: int, reset: int, spec: str) -> Register:
    return Register(name, offset, reset, fields(spec))


@dataclass(frozen=True)
class Description:
    """A peripheral's register map."""
    name: str
    registers: tuple[Register, ...]

    def renamed(self, name: str) -> "Description":
        """The same map for another instance (SPI1 ... SPI5)."""
        return Description(name, self.registers)

    def register(self, name: str) -> Register:
        for r in self.registers:
            if r.name == name:
                return r
        raise KeyError(f"{self.name} has no register {name}")


class RegisterFile:
    """A peripheral built from its ``Description``; ``noted`` is the run's set of names
    already logged (it outlives a system reset: once a run)."""

    pollable: frozenset[int] = frozenset()

    def __init__(self, description: Description, noted: set[str] | None = None) -> None:
        self.description = description
        self.name = description.name
        self.noted = noted if noted is not None else set()
        self.by_offset = {r.offset: r for r in description.registers}
        self.regs = {r.offset: r.reset for r in description.registers}
        self.on_read: dict[int, Callable[[], int]] = {}
        self.on_write: dict[int, Callable[[int, int], None]] = {}
        # a register without behaviour changes only when written: a poll of it can be skipped
        self.pollable = frozenset(self.by_offset)

    def offset(self, name: str) -> int:
        return self.description.register(name).offset

    def behave(self, name: str, read: Callable[[], int] | None = None,
               write: Callable[[int, int], None] | None = None) -> None:
        """Attach behaviour to register ``name``: ``read()`` gives its value, ``write(old,
        new)`` hears each write after the access rules made ``new``."""
        off = self.offset(name)
        if read is not None:
            self.on_read[off] = read
        if write is not None:
            self.on_write[off] = write

    def _note(self, off: int) -> None:
        r = self.by_offset.get(off)
        what = f"{self.name}.{r.name}" if r else f"{self.name}+0x{off:03X}"
        if what in self.noted:
            return
        self.noted.add(what)
        if r:
            log.warning("firmware used %s, a register without behaviour (reads its reset "
                        "value, keeps what is written)", what)
        else:
            log.warning("firmware used %s, where %s has no register (reads 0, writes are "
                        "dropped)", what, self.name)

    def read(self, off: int) -> int:
        reader = self.on_read.get(off)
        if reader is not None:
            return reader()
        r = self.by_offset.get(off)
        if r is None or off not in self.on_write:
            self._note(off)
        if r is None:
            return 0
        value = self.regs[off]
        clear = r.mask(Access.RC_R)
        if clear:
            self.regs[off] = value & ~clear
        return value & ~r.mask(Access.W)

    def after_write(self, r: Register, old: int, value: int) -> int:
        """The register's value after ``value`` is written over ``old``, by its fields'
        access rules (bits no field covers keep their value)."""
        keep = old & ~r.mask(Access.RW, Access.W, Access.RC_W1, Access.RC_W0, Access.T,
                             Access.RS)
        new = keep | (value & r.mask(Access.RW, Access.W))
        new |= old & r.mask(Access.RC_W1) & ~value
        new |= old & r.mask(Access.RC_W0) & value
        new |= (old ^ value) & r.mask(Access.T)
        new |= (old | value) & r.mask(Access.RS)
        return new

    def write(self, off: int, value: int) -> None:
        r = self.by_offset.get(off)
        if r is None:
            self._note(off)
            return
        old = self.regs[off]
        new = self.after_write(r, old, value)
        self.regs[off] = new & ~r.mask(Access.W)
        behaviour = self.on_write.get(off)
        if behaviour is None:
            self._note(off)
        else:
            behaviour(old, new)

    def set_bits(self, name: str, mask: int) -> None:
        """The hardware sets flags (an event): whatever their access."""
        self.regs[self.offset(name)] |= mask

    def clear_bits(self, name: str, mask: int) -> None:
        self.regs[self.offset(name)] &= ~mask

    def value(self, name: str) -> int:
        return self.regs[self.offset(name)]

    def field_value(self, reg_name: str, field: str) -> int:
        f = self.description.register(reg_name).field(field)
        return (self.regs[self.offset(reg_name)] & f.mask) >> f.lsb
