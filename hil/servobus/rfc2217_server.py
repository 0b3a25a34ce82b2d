"""``hexhil bus --rfc2217 PORT``: the emulated line behind pyserial's RFC 2217 server.

A pty has no modem lines (setting RTS or DTR on one fails with ENOTTY), so a client that
drives them (RS-485 direction control, ``pyservos``) opens ``rfc2217://127.0.0.1:PORT``
instead: pyserial's ``PortManager`` takes the Telnet options and sets baud, RTS, DTR and
the rest on ``EmulatedPort``, which hands the bit rate to the bus (judged against each
servo's Baud Rate register, as on a pty) and keeps the lines. With ``rts_direction`` RTS
is the direction line, judged like the board's PA1 (hil/link/board_line.py): bytes written
while RTS is low (receive) do not reach the line (``tx_while_receiving``), a status that
arrives while it is high (transmit) is lost (``rx_while_transmitting``).
"""
from __future__ import annotations

import socket
from typing import Callable

from hexhil.hil.servobus.serial_server import RealTimeServer

TX_WHILE_RECEIVING = "tx_while_receiving"
RX_WHILE_TRANSMITTING = "rx_while_transmitting"


class EmulatedPort:
    """What ``serial.rfc2217.PortManager`` drives: the settings of the emulated adapter."""

    def __init__(self, server: RealTimeServer, rts_direction: bool = False) -> None:
        self.server = server
        self.rts_direction = rts_direction
        self._baudrate = server.bus.baud
        self.bytesize, self.parity, self.stopbits = 8, "N", 1
        self.xonxoff = self.rtscts = self.break_condition = False
        self.rts = self.dtr = False
        self.cts = self.dsr = True          # the emulated adapter is always ready
        self.ri = self.cd = False

    @property
    def baudrate(self) -> int:
        return self._baudrate

    @baudrate.setter
    def baudrate(self, baud: int) -> None:
        if baud <= 0:
            raise ValueError(f"baud rate {baud}")
        self._baudrate = int(baud)
        self.server.client_baud(self._baudrate)

    def reset_input_buffer(self) -> None:
        """Nothing is buffered here: bytes go to the line as they come."""

    def reset_output_buffer(self) -> None:
        """Nothing is buffered here: replies leave as they arrive."""

    def mistake(self, kind: str, detail: str) -> None:
        """A direction-line mistake, for the bus's master check (its violations)."""
        check = self.server.bus.monitor
        if check is not None and hasattr(check, "direction_mistake"):
            check.direction_mistake(self.server.bus.clock.t_us, kind, detail)


def serve_rfc2217(server: RealTimeServer, port: int, host: str,
                  announce: Callable[[str], None], rts_direction: bool = False) -> None:
    """Listen on host:port; serve RFC 2217 clients one at a time until SIGTERM/Ctrl-C
    (direction mistakes go to the bus's master check: the summary's violations)."""
    import serial.rfc2217

    emulated = EmulatedPort(server, rts_direction)
    srv = server.listen(port, host, announce, "rfc2217: rfc2217://")
    try:
        for conn in server.clients(srv):
            _serve_client(server, emulated, conn, serial.rfc2217.PortManager)
    finally:
        srv.close()


def _serve_client(server: RealTimeServer, emulated: EmulatedPort, conn: socket.socket,
                  manager_class) -> None:
    class Connection:
        """PortManager's way back to the client (Telnet negotiation and replies)."""

        @staticmethod
        def write(data: bytes) -> None:
            try:
                conn.sendall(data)
            except OSError:
                pass

    manager = manager_class(emulated, Connection())

    def read() -> bytes | None:
        try:
            raw = conn.recv(4096)
        except BlockingIOError:
            return b""
        except OSError:
            return None
        if not raw:
            return None
        data, lost = bytearray(), 0
        for piece in manager.filter(raw):     # RTS as it was when each byte came
            if emulated.rts_direction and not emulated.rts:
                lost += len(piece)
            else:
                data += piece
        if lost:
            emulated.mistake(TX_WHILE_RECEIVING, f"{lost} bytes written while RTS was low "
                                                 "(receive): they did not reach the line")
        return bytes(data)

    def write(data: bytes) -> None:
        if emulated.rts_direction and emulated.rts:
            emulated.mistake(RX_WHILE_TRANSMITTING, f"{len(data)} status bytes arrived while "
                                                    "RTS was high (transmit): the receiver was off")
            return
        Connection.write(b"".join(manager.escape(data)))

    try:
        server.pump(conn.fileno(), read, write)
    finally:
        conn.close()
