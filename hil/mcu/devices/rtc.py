"""RTC and its backup registers (RM0383 22.6) as a register file: the calendar, alarms,
wakeup timer, time stamp, tamper and the 20 backup registers, each field with its access.
No behaviour is attached here (the calendar does not run, INITF never comes); the RTC's
model attaches it by name.
"""
from __future__ import annotations

from hil.mcu.registers import Description, reg

ALARM = ("SU:0-3:rw ST:4-6:rw MSK1:7:rw MNU:8-11:rw MNT:12-14:rw MSK2:15:rw HU:16-19:rw "
         "HT:20-21:rw PM:22:rw MSK3:23:rw DU:24-27:rw DT:28-29:rw WDSEL:30:rw MSK4:31:rw")
TIME = "SU:0-3:{a} ST:4-6:{a} MNU:8-11:{a} MNT:12-14:{a} HU:16-19:{a} HT:20-21:{a} PM:22:{a}"
DATE = "DU:0-3:{a} DT:4-5:{a} MU:8-11:{a} MT:12:{a} WDU:13-15:{a}"

RTC = Description("RTC", (
    reg("TR", 0x00, 0x00000000, TIME.format(a="rw")),
    reg("DR", 0x04, 0x00002101, DATE.format(a="rw") + " YU:16-19:rw YT:20-23:rw"),
    reg("CR", 0x08, 0x00000000,
        "WUCKSEL:0-2:rw TSEDGE:3:rw REFCKON:4:rw BYPSHAD:5:rw FMT:6:rw DCE:7:rw ALRAE:8:rw "
        "ALRBE:9:rw WUTE:10:rw TSE:11:rw ALRAIE:12:rw ALRBIE:13:rw WUTIE:14:rw TSIE:15:rw "
        "ADD1H:16:w SUB1H:17:w BKP:18:rw COSEL:19:rw POL:20:rw OSEL:21-22:rw COE:23:rw"),
    reg("ISR", 0x0C, 0x00000007,
        "ALRAWF:0:r ALRBWF:1:r WUTWF:2:r SHPF:3:r INITS:4:r RSF:5:rc_w0 INITF:6:r INIT:7:rw "
        "ALRAF:8:rc_w0 ALRBF:9:rc_w0 WUTF:10:rc_w0 TSF:11:rc_w0 TSOVF:12:rc_w0 "
        "TAMP1F:13:rc_w0 TAMP2F:14:rc_w0 RECALPF:16:r"),
    reg("PRER", 0x10, 0x007F00FF, "PREDIV_S:0-14:rw PREDIV_A:16-22:rw"),
    reg("WUTR", 0x14, 0x0000FFFF, "WUT:0-15:rw"),
    reg("CALIBR", 0x18, 0x00000000, "DC:0-4:rw DCS:7:rw"),
    reg("ALRMAR", 0x1C, 0x00000000, ALARM),
    reg("ALRMBR", 0x20, 0x00000000, ALARM),
    reg("WPR", 0x24, 0x00000000, "KEY:0-7:w"),
    reg("SSR", 0x28, 0x00000000, "SS:0-15:r"),
    reg("SHIFTR", 0x2C, 0x00000000, "SUBFS:0-14:w ADD1S:31:w"),
    reg("TSTR", 0x30, 0x00000000, TIME.format(a="r")),
    reg("TSDR", 0x34, 0x00000000, DATE.format(a="r")),
    reg("TSSSR", 0x38, 0x00000000, "SS:0-15:r"),
    reg("CALR", 0x3C, 0x00000000, "CALM:0-8:rw CALW16:13:rw CALW8:14:rw CALP:15:rw"),
    reg("TAFCR", 0x40, 0x00000000,
        "TAMP1E:0:rw TAMP1TRG:1:rw TAMPIE:2:rw TAMP2E:3:rw TAMP2TRG:4:rw TAMPTS:7:rw "
        "TAMPFREQ:8-10:rw TAMPFLT:11-12:rw TAMPPRCH:13-14:rw TAMPPUDIS:15:rw "
        "TAMP1INSEL:16:rw TSINSEL:17:rw ALARMOUTTYPE:18:rw"),
    reg("ALRMASSR", 0x44, 0x00000000, "SS:0-14:rw MASKSS:24-27:rw"),
    reg("ALRMBSSR", 0x48, 0x00000000, "SS:0-14:rw MASKSS:24-27:rw"),
    *(reg(f"BKP{i}R", 0x50 + 4 * i, 0, "BKP:0-31:rw") for i in range(20)),
))
