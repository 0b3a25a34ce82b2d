"""I2C1-3 (RM0383 18) as masters on a bus with its pull-ups and no device on it, as on this
board: START gives SB, MSL and BUSY one SCL period later; the address written to DR is not
acknowledged: AF after its nine SCL periods (with ITERREN the error interrupt); STOP frees
the bus a period later. So ``HAL_I2C_IsDeviceReady`` and ``HAL_I2C_Master_Transmit`` to a
sensor that is not there return HAL_ERROR (AF) in microseconds, as the chip does. The SCL
period is CCR's (standard: 2 CCR; fast: 3 CCR, or 25 CCR with DUTY, of PCLK1). Not
modelled: a device, slave mode, SMBus, PEC, DMA.
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.registers import Description, RegisterFile, reg
from hexhil.hil.mcu.timebase import FS_PER_S

I2C = Description("I2C", (
    reg("CR1", 0x00, 0, "PE:0:rw SMBUS:1:rw SMBTYPE:3:rw ENARP:4:rw ENPEC:5:rw ENGC:6:rw "
        "NOSTRETCH:7:rw START:8:rw STOP:9:rw ACK:10:rw POS:11:rw PEC:12:rw ALERT:13:rw "
        "SWRST:15:rw"),
    reg("CR2", 0x04, 0, "FREQ:0-5:rw ITERREN:8:rw ITEVTEN:9:rw ITBUFEN:10:rw DMAEN:11:rw "
        "LAST:12:rw"),
    reg("OAR1", 0x08, 0, "ADD0:0:rw ADD:1-7:rw ADD8_9:8-9:rw ADDMODE:15:rw"),
    reg("OAR2", 0x0C, 0, "ENDUAL:0:rw ADD2:1-7:rw"),
    reg("DR", 0x10, 0, "DR:0-7:rw"),
    reg("SR1", 0x14, 0, "SB:0:r ADDR:1:r BTF:2:r ADD10:3:r STOPF:4:r RXNE:6:r TXE:7:r "
        "BERR:8:rc_w0 ARLO:9:rc_w0 AF:10:rc_w0 OVR:11:rc_w0 PECERR:12:rc_w0 "
        "TIMEOUT:14:rc_w0 SMBALERT:15:rc_w0"),
    reg("SR2", 0x18, 0, "MSL:0:r BUSY:1:r TRA:2:r GENCALL:4:r SMBDEFAULT:5:r SMBHOST:6:r "
        "DUALF:7:r PEC:8-15:r"),
    reg("CCR", 0x1C, 0, "CCR:0-11:rw DUTY:14:rw F_S:15:rw"),
    reg("TRISE", 0x20, 0x0002, "TRISE:0-5:rw"),
    reg("FLTR", 0x24, 0, "DNF:0-3:rw ANFOFF:4:rw"),
))

PE, START, STOP, SWRST = 1, 1 << 8, 1 << 9, 1 << 15
SB, ADDR, AF = 1, 1 << 1, 1 << 10
MSL, BUSY = 1, 1 << 1
ITERREN = 1 << 8


class I2cBus(RegisterFile):
    def __init__(self, board: Any, row: Any) -> None:
        super().__init__(I2C.renamed(row.name), board.noted)
        self.board, self.error_irq = board, row.irq_numbers[1]
        self.started = board.events.timer(self._started)
        self.nacked = board.events.timer(self._nacked)
        self.stopped = board.events.timer(self._stopped)
        self.behave("CR1", write=self._cr1)
        self.behave("DR", write=self._dr)
        self.behave("SR1", write=lambda old, new: self._line())
        self.behave("CR2", write=lambda old, new: self._line())
        for name in ("CCR", "TRISE", "OAR1", "OAR2", "FLTR"):   # configuration
            self.behave(name, write=lambda old, new: None)

    def _period_fs(self, n: int) -> int:
        ccr = self.value("CCR")
        scale = (25 if ccr & 1 << 14 else 3) if ccr & 1 << 15 else 2
        return n * scale * max(ccr & 0xFFF, 1) * FS_PER_S // self.board.rcc.pclk1_hz

    def _cr1(self, old: int, new: int) -> None:
        now = self.board.core.now_fs()
        if new & SWRST:
            self.regs.update({self.offset(n): 0 for n in ("SR1", "SR2")})
            for timer in (self.started, self.nacked, self.stopped):
                timer.clear()
        elif new & START and new & PE:
            self.started.set(now + self._period_fs(1))
        elif new & STOP and new & PE:
            self.stopped.set(now + self._period_fs(1))

    def _started(self, at_fs: int) -> None:
        self.clear_bits("CR1", START)
        self.set_bits("SR1", SB)
        self.set_bits("SR2", MSL | BUSY)

    def _dr(self, old: int, new: int) -> None:
        if self.value("SR1") & SB:          # the address: nobody answers it
            self.clear_bits("SR1", SB)
            self.nacked.set(self.board.core.now_fs() + self._period_fs(9))

    def _nacked(self, at_fs: int) -> None:
        self.set_bits("SR1", AF)
        self._line()

    def _stopped(self, at_fs: int) -> None:
        self.clear_bits("CR1", STOP)
        self.clear_bits("SR2", MSL | BUSY)

    def _line(self) -> None:
        level = bool(self.value("SR1") & AF and self.value("CR2") & ITERREN)
        self.board.irq_lines(self.error_irq, self, level)
