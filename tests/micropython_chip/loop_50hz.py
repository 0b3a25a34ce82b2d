# main.py: a 50 Hz control loop: a ping on the servo line, some float work, then sleep_ms to
# the next 20 ms mark.
import math
import time
from machine import Pin, UART

d = Pin("A1", Pin.OUT, value=0)
u = UART(2, baudrate=1000000, timeout=10, timeout_char=2)
PING = bytes((0xFF, 0xFF, 1, 2, 1, 0xFB))


def work(n):
    s = 0.0
    for i in range(n):
        s += math.atan2(math.sin(i * 0.1), math.cos(i * 0.2)) * math.sqrt(i + 1.0)
    return s


t = time.ticks_ms()
while True:
    d.value(1)
    u.write(PING)
    while not u.txdone():
        pass
    d.value(0)
    u.read(6)
    work(60)
    t = time.ticks_add(t, 20)
    time.sleep_ms(max(0, time.ticks_diff(t, time.ticks_ms())))
