"""A port object for the official ``dynamixel_sdk``: records what the SDK writes and answers
with status packets built by ``protocol.dynamixel.v1``, so one exchange checks both directions."""
from __future__ import annotations

from hexhil.protocol.dynamixel import v1 as dxl


class ScriptedPort:
    """The PortHandler methods PacketHandler(1.0) calls; ``table`` answers READs per id."""

    def __init__(self, table: dict[int, bytes] | None = None, error: int = 0) -> None:
        self.is_using = False
        self.written: list[bytes] = []
        self.table = table or {}
        self.error = error
        self._rx = bytearray()
        self._timeout_left = 0

    # --- PortHandler API -----------------------------------------------------------
    def clearPort(self) -> None:
        self._rx.clear()

    def writePort(self, packet: list[int]) -> int:
        data = bytes(packet)
        self.written.append(data)
        parsed = dxl.Parser().feed(data)
        if len(parsed) == 1 and parsed[0].id != dxl.BROADCAST_ID:
            self._rx.extend(self._reply(parsed[0]))
        return len(data)

    def readPort(self, length: int) -> list[int]:
        out = list(self._rx[:length])
        del self._rx[:length]
        return out

    def getBytesAvailable(self) -> int:
        return len(self._rx)

    def setPacketTimeout(self, packet_length: int) -> None:
        self._timeout_left = 3  # polls before isPacketTimeout says so (no wall clock)

    def isPacketTimeout(self) -> bool:
        self._timeout_left -= 1
        return self._timeout_left < 0

    # --- the servo's side ------------------------------------------------------------
    def _reply(self, pkt: dxl.Packet) -> bytes:
        if pkt.code == dxl.READ:
            address, length = pkt.params[0], pkt.params[1]
            data = self.table.get(pkt.id, bytes(50))[address:address + length]
            return dxl.status(pkt.id, self.error, data)
        return dxl.status(pkt.id, self.error)
