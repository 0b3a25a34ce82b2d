"""Simulator-link wire format, versions 1 and 2, shared by firmware/hal/sim.py and hil/link/firmware_process.py.

docs/link.md is the specification (byte tables, limits, the conformance suite); the JSON
inside the hello and the events is protocol/link_schema.py. Every client message is
``op (1 byte) | length (u16 LE) | payload``. Posted messages (W, C, E) get no answer: the
client batches them in front of its next request. On version 1 a cycle costs one round
trip per bus read plus one for the end-of-cycle sleep; version 2 (negotiated in the hello)
adds R, a cycle's status reads in one round trip. Replies are ``length (u16 LE) | payload`` and
start with the virtual time ``t_us`` (u64 LE) after the request; an error reply has
``t_us = ERROR_T_US`` and utf-8 text, and the host closes the link after it.

Requests (client -> host):
  H hello       u8 version, runtime name (ascii)         reply: t_us, u8 version, u8 switches,
                                                                config JSON
  X transact    u16 nrx, u32 timeout_us, tx bytes        reply: t_us, rx bytes (<= nrx)
  S sleep       u64 wake_us                              reply: t_us, u8 flags, u8 switches,
                                                                u8 n, n x (u16 id, u8 dlc, 8 data)
  M more        (empty): the CAN frames a reply with FLAG_MORE left queued; same reply as S
  L line        u64 at_us, u8 flags, u16 nrx, tx bytes   reply: t_us, u8 flags, u8 switches,
                (the virtual board's UART and direction        u64 next_rx_us, u16 pending,
                pin: docs/link.md "L line")                    rx bytes (<= nrx)
  R reads       (version 2) u8 n, n x read: the cycle's     reply: t_us, u8 n, n x attempt
                status reads in one exchange, retried and      (u64 t_us, u16 got, rx bytes)
                skipped by the rule of docs/link.md "R reads"
Posted:
  W write       tx bytes (UART write, no reply expected)
  C can         u16 id, u8 dlc, data (dlc bytes)
  E event       u8 kind, utf-8 text (kinds below)
  T timed event u64 at_us, u8 kind, utf-8 text (an event of that virtual time)
  D direction   u64 turn_us, u8 level (the virtual board's direction pin turned; L)
  B baud        u32 bit/s (the client's servo UART rate, the C SDK's HAL_UART_Init)
"""
VERSION = 1          # the base version: every client and host speaks it
VERSION_READS = 2    # version 1 plus R (a cycle's status reads in one exchange)
VERSIONS = (VERSION, VERSION_READS)   # a host refuses a hello of any other with an error reply

OP_HELLO = 0x48   # 'H'
OP_TRANSACT = 0x58  # 'X'
OP_SLEEP = 0x53   # 'S'
OP_MORE = 0x4D    # 'M'
OP_LINE = 0x4C    # 'L': the virtual board's UART and direction line (docs/link.md)
OP_WRITE = 0x57   # 'W'
OP_CAN = 0x43     # 'C'
OP_EVENT = 0x45   # 'E'
OP_DIRECTION = 0x44  # 'D': the virtual board's direction pin turned (docs/link.md)
OP_BAUD = 0x42    # 'B': the client's servo UART runs at this rate (docs/link.md)
OP_READS = 0x52   # 'R': version 2, a cycle's status reads in one exchange (docs/link.md)
OP_EVENT_AT = 0x54  # 'T': an event of a given virtual time, the ELF board's console line
REQUEST_OPS = (OP_HELLO, OP_TRANSACT, OP_SLEEP, OP_MORE, OP_LINE, OP_READS)
POSTED_OPS = (OP_WRITE, OP_CAN, OP_EVENT, OP_DIRECTION, OP_BAUD, OP_EVENT_AT)

FLAG_END = 0x01   # sleep reply: the run is over, exit the loop
FLAG_MORE = 0x02  # sleep or more reply: further CAN frames are queued, ask with OP_MORE

EVENT_LOG = 0        # free text
EVENT_EXCEPTION = 1  # unhandled exception, text = traceback
EVENT_STOP = 2       # safe stop, text = reason
EVENT_STATS = 3      # JSON object of the firmware's counters at exit (link_schema.STATS)
EVENT_TACTILE = 4    # JSON: a switch edge or trajectory change (link_schema.TACTILE)
EVENT_FAULT = 5      # JSON: link_schema.FAULT

HEADER_LEN = 3
CAN_RECORD_LEN = 11  # u16 id, u8 dlc, 8 data bytes
CAN_MAX_DLC = 8
MAX_REPLY_LEN = 2048     # a reply's payload, t_us included: the client's receive buffer
SLEEP_HEAD_LEN = 11      # t_us, flags, switches, n
MAX_CAN_PER_REPLY = (MAX_REPLY_LEN - SLEEP_HEAD_LEN) // CAN_RECORD_LEN  # 185
MAX_RX_LEN = MAX_REPLY_LEN - 8   # the most a transact may ask for (nrx)
ERROR_T_US = 0xFFFFFFFFFFFFFFFF  # t_us of an error reply (virtual time never gets there)
ERROR_MARK = b"\xff\xff\xff\xff\xff\xff\xff\xff"  # ERROR_T_US as it is on the wire
ENV_PORT = "HEXHIL_LINK_PORT"
ENV_PATH = "HEXHIL_LINK_PATH"   # a Unix socket instead of the port: our HAL, firmware/hal/sim.py
ENV_SPIN_US = "HEXHIL_LINK_SPIN_US"   # poll this long for a reply before blocking (0: never)
ENV_HOST_PID = "HEXHIL_LINK_HOST_PID"   # the host's process id, beside ENV_SPIN_US
ENV_BOARD = "HEXHIL_BOARD"   # set (to BOARD_NAME) when the firmware runs on the virtual board
BOARD_NAME = "stm32f411"

LINE_DIR_TX = 0x01   # line request flag: the direction pin is high (transmit)
LINE_POLL = 0x02     # line request flag: a busy-wait poll, not an action of the firmware
LINE_HEAD_LEN = 11   # line request: u64 at_us, u8 flags, u16 nrx
DIRECTION_LEN = 9    # direction message: u64 turn_us, u8 level
BAUD_LEN = 4         # baud message: u32 bit/s
EVENT_AT_HEAD_LEN = 9   # timed event: u64 at_us, u8 kind (the text follows)
LINE_REPLY_HEAD_LEN = 20  # line reply: t_us, u8 flags, u8 switches, u64 next_rx_us, u16 pending
NO_RX = 0            # line reply's next_rx_us when no byte is on its way
READ_HEAD_LEN = 11   # a read of R: u8 id, u8 nparams, u8 retries, u8 flags, u8 skip, u16 nrx,
                     # u32 timeout_us (then u8 ntx and the tx bytes)
READ_ECHO = 0x01     # read flag: the line echoes the master's bytes (the reply follows them)
NO_SKIP = 0xFF       # read's skip field: read whatever the earlier reads gave
ATTEMPT_HEAD_LEN = 10  # an attempt of R's reply: u64 t_us, u16 got (then the rx bytes)


class LinkError(OSError):
    """The link cannot go on: the host sent an error reply, or closed it, or broke a limit.
    The client reports it in one line and exits non-zero."""


def error_reply(text):
    """The bytes of an error reply carrying ``text`` (cut to fit ``MAX_REPLY_LEN``)."""
    body = ERROR_MARK + text.encode()[:MAX_REPLY_LEN - 8]
    n = len(body)
    return bytes((n & 0xFF, n >> 8)) + body
