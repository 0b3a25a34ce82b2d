"""Simulator-link wire format, shared by firmware/hal/sim.py and hil/link.py.

Every message is ``op (1 byte) | length (u16 LE) | payload``. Posted messages (W, C, E)
get no answer: the firmware batches them in front of its next request, so a cycle
costs one TCP round trip per bus read plus one for the end-of-cycle sleep.
Replies are ``length (u16 LE) | payload`` and always start with the virtual time
``t_us`` (u64 LE) after the request.

Requests (firmware -> host):
  H hello       payload: runtime name (ascii)            reply: t_us, switches u8, config JSON
  X transact    u16 nrx, u32 timeout_us, tx bytes        reply: t_us, rx bytes (<= nrx)
  S sleep       u64 wake_us                              reply: t_us, flags u8, switches u8,
                                                                u8 n, n x (u16 id, u8 dlc, 8 data)
Posted:
  W write       tx bytes (UART write, no reply expected)
  C can         u16 id, u8 dlc, data
  E event       u8 kind, utf-8 text (kinds below)
"""
OP_HELLO = 0x48   # 'H'
OP_TRANSACT = 0x58  # 'X'
OP_SLEEP = 0x53   # 'S'
OP_WRITE = 0x57   # 'W'
OP_CAN = 0x43     # 'C'
OP_EVENT = 0x45   # 'E'

FLAG_END = 0x01   # sleep reply: the run is over, exit the loop

EVENT_LOG = 0        # free text
EVENT_EXCEPTION = 1  # unhandled exception, text = traceback
EVENT_STOP = 2       # safe stop, text = reason
EVENT_STATS = 3      # JSON object of the firmware's counters at exit
EVENT_TACTILE = 4    # JSON: a switch edge or trajectory change
EVENT_FAULT = 5      # JSON: {"name": ..., "detail": ...}

HEADER_LEN = 3
CAN_RECORD_LEN = 11  # u16 id, u8 dlc, 8 data bytes
ENV_PORT = "HEXHIL_LINK_PORT"
