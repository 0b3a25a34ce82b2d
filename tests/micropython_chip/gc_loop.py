# main.py: the garbage collector in a loop with interrupts on (SysTick, the UART's), then one
# line with how many collections ran and the heap's free bytes.
import gc
import time

t0 = time.ticks_ms()
n = 0
while time.ticks_diff(time.ticks_ms(), t0) < 200:
    gc.collect()
    n += 1
print('{"collections": %d, "free": %d}' % (n, gc.mem_free()))
while True:
    time.sleep_ms(100)
