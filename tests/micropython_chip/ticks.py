# main.py: time.ticks_us arithmetic as on the board: ticks_add/ticks_diff wrapping at the
# period, sleep_us and sleep_ms measured in ticks_us, ticks_us against ticks_ms.
import time

MAX = time.ticks_add(0, -1)
wrap = time.ticks_diff(time.ticks_add(MAX, 5), MAX)
back = time.ticks_diff(MAX, time.ticks_add(MAX, 5))
t0 = time.ticks_us()
time.sleep_us(500)
t1 = time.ticks_us()
time.sleep_ms(20)
t2 = time.ticks_us()
m0 = time.ticks_ms()
u0 = time.ticks_us()
while time.ticks_diff(time.ticks_ms(), m0) < 50:
    pass
u1 = time.ticks_us()
print('{"max": %d, "wrap": %d, "back": %d, "sleep_us_500": %d, "sleep_ms_20": %d, "spin_ms_50": %d}'
      % (MAX, wrap, back, time.ticks_diff(t1, t0), time.ticks_diff(t2, t1),
         time.ticks_diff(u1, u0)))
while True:
    time.sleep_ms(100)
