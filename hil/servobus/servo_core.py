"""The AX-12s' SYNC_WRITE and READ compiled (hil/servobus/servo_core.c), through ctypes.

Every cycle the firmware's SYNC_WRITE reaches all 18 servos; each catches up its health,
finds its entry, checks the write against its control table and drives its joint. In
Python that was about a third of the host's cycle; ``hx_sync_write`` does it for the whole
line in one call, and ``hx_read`` answers a status read (catch-up, the Present registers,
the status packet and its checksum); ``hx_state_rows`` packs every servo's ``state_row``
for the recorder's 10 Hz ground truth. They step the same state as the Python servos (their
and their health's ctypes fields, ax12_servo.py ``Servo`` and health.py ``ServoHealth``,
their control tables and the world's compiled drive bank, hil/world/drive_core.c) by the
same compiled rules (servo_rules.py). A servo the C code does not serve (an actuator other
than a world's joint, deaf, finishing an EEPROM write, a Present Position fault) is handed
to its own ``handle``, in the line's order.

The package builds ``_servo_core.so`` beside this file (setup.py, the pinned ziglang's cc);
without it no servo is made (the servos' rules, servo_rules.py, are compiled only).
"""
from __future__ import annotations

import ctypes
from typing import Any, Sequence

import numpy as np

from hexhil.hil.seams import HeldSample
from hexhil.hil.servobus import servo_rules
from hexhil.hil.servobus.servo_layout import LAYOUT, STATE_ROW
from hexhil.hil.world import drive_core
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

LIBRARY = servo_rules.LIBRARY
_P = ctypes.c_void_p


class _Bank(ctypes.Structure):
    _fields_ = LAYOUT.fields("bank")


def _load() -> Any:
    """The library's functions, (hx_sync_write, hx_read, hx_state_rows), or None."""
    lib = servo_rules.library()   # missing: servo_rules refuses every servo in one line
    if lib is None:
        return None
    sync, read, rows = lib.hx_sync_write, lib.hx_read, lib.hx_state_rows
    sync.argtypes = [_P, ctypes.c_int, ctypes.c_int64, ctypes.c_char_p, ctypes.c_int, _P]
    read.argtypes = [_P, ctypes.c_int, ctypes.c_int64, ctypes.c_int, ctypes.c_int, _P]
    rows.argtypes = [_P, _P]
    sync.restype = read.restype = ctypes.c_int
    rows.restype = None
    return sync, read, rows


_LIB = _load()


def available() -> bool:
    return _LIB is not None


def _address(a: np.ndarray) -> int:
    return a.ctypes.data


class StateRows(HeldSample[tuple]):
    """The bank's ``state_row``s as ``hx_state_rows`` packed them, unpacked where the
    recorder encodes them: a 10 Hz ground-truth sample costs the run one call instead of
    18 (about 19 us), and a window's pickle 800 bytes a sample instead of 162
    objects."""

    @staticmethod
    def _make(packed: bytes) -> list[tuple]:
        return list(STATE_ROW.iter_unpack(packed))


class ServoBank:
    """``hx_sync_write``, ``hx_read`` and ``hx_state_rows`` bound to one line's servos at
    its baud (``Bus._same``): built when the line is re-indexed; ``None`` from ``build`` when
    none of them drives a MuJoCo joint (then their own ``handle`` serves them all)."""

    def __init__(self, servos: Sequence[Any], joints: list[tuple[dict[str, np.ndarray], int]
                                                           | None]) -> None:
        n = len(servos)
        self.servos = list(servos)
        arrays = next(j[0] for j in joints if j is not None)
        # the C code serves the servos on this world's joints; the others (another device
        # on the line, another actuator) have no state there: NULL, joint -1
        served = [j is not None and j[0] is arrays for j in joints]
        self._tables = [(ctypes.c_uint8 * len(s.table)).from_buffer(s.table) if ok else None
                        for s, ok in zip(servos, served)]
        self._keep: list[Any] = [arrays, self._tables]
        servo_p = (_P * n)(*(ctypes.addressof(s) if ok else None
                             for s, ok in zip(servos, served)))
        health_p = (_P * n)(*(ctypes.addressof(s.health) if ok else None
                              for s, ok in zip(servos, served)))
        table_p = (_P * n)(*(ctypes.addressof(t) if t is not None else None
                             for t in self._tables))
        joint = np.array([j[1] if ok else -1 for j, ok in zip(joints, served)], dtype=np.int32)
        original = np.array([ok and s.edition == ax12.EDITION_ORIGINAL
                             for s, ok in zip(servos, served)], dtype=np.int32)
        self._keep += [servo_p, health_p, table_p, joint, original]
        self._bank = _Bank(
            n, ctypes.addressof(servo_p), ctypes.addressof(health_p), ctypes.addressof(table_p),
            _address(joint), _address(original), _address(servo_rules.CELLS),
            _address(servo_rules.POSITION_RAD), _address(servo_rules.SPEED_RAD_S),
            arrays["drives"], drive_core.STATE_FN, drive_core.COMMAND_FN)
        self.ref = ctypes.addressof(self._bank)   # the bank's address (status_reads.py too)
        self._sync, self._read, self._rows = _LIB
        self._rows_out = ctypes.create_string_buffer(n * STATE_ROW.size)
        self._rows_at = ctypes.addressof(self._rows_out)
        self._all_served = all(served)
        self._out = ctypes.create_string_buffer(ax12.TABLE_SIZE + 6)
        self._out_at = ctypes.addressof(self._out)
        self._changed = ctypes.c_int32()   # hx_sync_write's: an ID or Baud Rate changed
        self.changed_address = ctypes.addressof(self._changed)
        self.index = {id(s): i for i, (s, ok) in enumerate(zip(servos, served)) if ok}
        # ID -> the bank index of the one servo it reaches, -1 (none, two, or not served)
        ids = [s.id for s in servos]
        by_id = np.full(256, -1, dtype=np.int16)
        for i in self.index.values():
            dev_id = servos[i].id
            if ids.count(dev_id) == 1:
                by_id[dev_id] = i
        self._keep.append(by_id)
        self.by_id_address = _address(by_id)
        self.n = n
        self.advance = arrays["advance"]   # the world's: what the first servo's catch-up did
        self.next_step_us = arrays.get("next_step_us")   # when its advance next steps

    @classmethod
    def build(cls, servos: Sequence[Any], servo_class: type) -> ServoBank | None:
        """The bank of ``servos``, those of exactly ``servo_class`` (ax12_servo.Servo, not a
        test's subclass with other rules) on one world's joints served in C."""
        if not available() or not servos:
            return None
        joints = []
        for s in servos:
            fn = getattr(s.actuator, "joint_buffers", None) if type(s) is servo_class else None
            joints.append(None if fn is None else fn())
        if all(j is None for j in joints):
            return None
        return cls(servos, joints)

    def sync_write(self, params: bytes, t_us: int) -> bool:
        """Every servo of the bank takes the broadcast SYNC_WRITE ``params`` at ``t_us``, in
        order (``Bus._dispatch``'s): in C where it can, each one it leaves by its own
        ``handle``. True when one's ID or Baud Rate changed (the line re-indexes)."""
        self.advance(t_us)
        self._changed.value = 0
        return self.finish_sync_write(
            self._sync(self.ref, 0, t_us, params, len(params), self.changed_address), params, t_us)

    def finish_sync_write(self, i: int, params: bytes, t_us: int) -> bool:
        """A SYNC_WRITE the C code carried out up to servo ``i``, which it left to its own
        ``handle`` (reads_core.c too): the rest, in order. True when one's ID or Baud Rate
        changed, here or in C (``changed_address``)."""
        servos, n, sync, ref, size = self.servos, self.n, self._sync, self.ref, len(params)
        changed, at = self._changed, self.changed_address
        while i < n:
            s = servos[i]
            s.handle(dxl.SYNC_WRITE, params, True, t_us)   # broadcast: no reply
            if s.address_changed:
                changed.value = 1
            i = sync(ref, i + 1, t_us, params, size, at)
        return bool(changed.value)

    def state_rows(self, servos: Sequence[Any]) -> StateRows | None:
        """``[s.state_row() for s in servos]`` in one call, where ``servos`` are this bank's,
        in its order, each on a MuJoCo joint; else None."""
        if not self._all_served or list(servos) != self.servos:
            return None
        self._rows(self.ref, self._rows_at)
        return StateRows(self._rows_out.raw)

    def read(self, servo: Any, params: bytes, t_us: int) -> bytes | None | bool:
        """``servo`` takes a READ at ``t_us``: its status packet, None when it answers
        nothing, False when its own ``handle`` must answer (not in the bank, a Present
        Position fault, not two parameters, or the C code left it: deaf, busy)."""
        i = self.index.get(id(servo))
        if i is None or servo.reading is not None or len(params) != 2:
            return False
        n = self._read(self.ref, i, t_us, params[0], params[1], self._out_at)
        if n > 0:
            return self._out.raw[:n]
        return None if n == 0 else False
