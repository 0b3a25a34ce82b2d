# main.py: the six leg switches (PB0-PB5, pull-ups, pressed = 0) as pin interrupts on both
# edges; every 10 ms the levels are polled too. After 1.5 s one line: the edges each handler
# counted, the level changes the poll saw, the last levels.
import time
from machine import Pin

NAMES = ("B0", "B1", "B2", "B3", "B4", "B5")
pins = [Pin(n, Pin.IN, Pin.PULL_UP) for n in NAMES]
edges = [0] * 6


def handler(i):
    def count(_pin):
        edges[i] += 1
    return count


for i, p in enumerate(pins):
    p.irq(handler(i), Pin.IRQ_RISING | Pin.IRQ_FALLING)
last = [p.value() for p in pins]
changes = [0] * 6
t0 = time.ticks_ms()
while time.ticks_diff(time.ticks_ms(), t0) < 1500:
    time.sleep_ms(10)
    now = [p.value() for p in pins]
    for i in range(6):
        if now[i] != last[i]:
            changes[i] += 1
    last = now
print('{"edges": %s, "changes": %s, "levels": %s}' % (edges, changes, last))
while True:
    time.sleep_ms(100)
