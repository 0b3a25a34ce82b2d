"""The emulated board's side of the simulator link (protocol/sim_link.py, docs/link.md).

The ELF itself knows nothing of the link: the board's peripherals turn what the firmware
does at its pins into the virtual board's messages, as firmware/virtual_board/vboard.py
does for MicroPython. A byte burst on USART2 is a line request at its first byte's time,
a turn of PA1 a direction message, a byte arriving at the RX pin a line request at its
arrival, a console line a timed event (at its newline's end), a bxCAN frame a CAN
message, and a quiet millisecond a sleep to now (the world, switches and CAN input move
on). The host answers it all with
hil/link/ as for any firmware, so trace, replay, faults, master check and expectations work
unchanged; ``exchange`` is the in-process link (hil/link/firmware_process.py ``DirectConnection``).
"""
from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Any, Callable

from hexhil.protocol import sim_link
from hexhil.protocol.errors import UserError

RUNTIME_NAME = b"stm32f411-elf"


@dataclass
class Reply:
    t_us: int
    ended: bool
    switches: int
    next_rx_us: int = 0          # 0: nothing on its way
    pending: int = 0
    rx: bytes = b""
    can: tuple[tuple[int, bytes], ...] = ()


class LinkClient:
    def __init__(self, exchange: Callable[[bytes, bool], bytes]) -> None:
        self._exchange = exchange
        self._out = bytearray()
        self.t_us = 0
        self.config: dict[str, Any] = {}
        self.requests = 0
        # PA1's turns the compiled board made (hil/mcu/board_core.py ``NativeBoard.turns``)
        self.turns: Callable[[], list[tuple[int, int]]] | None = None

    def _post(self, op: int, payload: bytes) -> None:
        self._drain()
        self._append(op, payload)

    def _append(self, op: int, payload: bytes) -> None:
        self._out += struct.pack("<BH", op, len(payload)) + payload

    def _drain(self) -> None:
        """The compiled board's turns of PA1, in order, before what comes after them."""
        if self.turns is not None:
            for turn_us, level in self.turns():
                self._append(sim_link.OP_DIRECTION, self._turned(turn_us, level))

    def _turned(self, turn_us: int, level: bool) -> bytes:
        return struct.pack("<QB", max(turn_us, self.t_us), level)

    def _request(self, op: int, payload: bytes) -> bytes:
        self._post(op, payload)
        data, self._out = bytes(self._out), bytearray()
        raw = self._exchange(data, False)
        self.requests += 1
        if len(raw) < 10:
            raise UserError("firmware link: the host closed the link")
        body = raw[2:2 + struct.unpack_from("<H", raw, 0)[0]]
        (t_us,) = struct.unpack_from("<Q", body, 0)
        if t_us == sim_link.ERROR_T_US:
            raise UserError(f"firmware link: {body[8:].decode(errors='replace')}")
        self.t_us = max(self.t_us, t_us)
        return body[8:]

    def close(self) -> None:
        self._drain()
        data, self._out = bytes(self._out), bytearray()
        self._exchange(data, True)

    def hello(self) -> int:
        body = self._request(sim_link.OP_HELLO, bytes((sim_link.VERSION,)) + RUNTIME_NAME)
        self.config = json.loads(body[2:].decode() or "{}")
        return body[1]

    def line(self, at_us: int, tx: bytes, direction_tx: bool, poll: bool, nrx: int) -> Reply:
        flags = (sim_link.LINE_DIR_TX if direction_tx else 0) | (sim_link.LINE_POLL if poll else 0)
        body = self._request(sim_link.OP_LINE, struct.pack("<QBH", max(at_us, self.t_us), flags,
                                                           nrx) + tx)
        flags, switches, next_us, pending = struct.unpack_from("<BBQH", body, 0)
        return Reply(self.t_us, bool(flags & sim_link.FLAG_END), switches,
                     0 if next_us == sim_link.NO_RX else next_us, pending,
                     bytes(body[sim_link.LINE_REPLY_HEAD_LEN - 8:]))

    def direction(self, turn_us: int, level: bool) -> None:
        self._post(sim_link.OP_DIRECTION, self._turned(turn_us, level))

    def sleep(self, wake_us: int) -> Reply:
        body = self._request(sim_link.OP_SLEEP, struct.pack("<Q", max(wake_us, self.t_us)))
        frames: list[tuple[int, bytes]] = []
        flags, switches = body[0], body[1]
        while True:
            n = body[2]
            for i in range(n):
                arb_id, dlc = struct.unpack_from("<HB", body, 3 + 11 * i)
                frames.append((arb_id, bytes(body[6 + 11 * i:6 + 11 * i + dlc])))
            if not flags & sim_link.FLAG_MORE:
                break
            body = self._request(sim_link.OP_MORE, b"")
            flags = body[0]
        return Reply(self.t_us, bool(flags & sim_link.FLAG_END), switches, can=tuple(frames))

    def event(self, kind: int, text: str) -> None:
        self._post(sim_link.OP_EVENT, bytes((kind,)) + text.encode()[:sim_link.MAX_REPLY_LEN])

    def event_at(self, at_us: int, kind: int, text: str) -> None:
        """An event of virtual time ``at_us`` (a console line's end, which may lie past
        the last request's time, or before the last reply's while a servo reply's bytes
        still arrive: the host takes it at that time)."""
        self._post(sim_link.OP_EVENT_AT, struct.pack("<QB", at_us, kind)
                   + text.encode()[:sim_link.MAX_REPLY_LEN])

    def fault(self, name: str, detail: str) -> None:
        """A mistake the board saw (a wrong baud, a byte cut by the direction pin)."""
        self.event(sim_link.EVENT_FAULT, json.dumps({"name": name, "detail": detail}))

    def can(self, arb_id: int, data: bytes) -> None:
        self._post(sim_link.OP_CAN, struct.pack("<HB", arb_id, len(data)) + data)
