# main.py: the garbage collector in a loop with interrupts on (SysTick, the UART's), the heap
# churned by short-lived buffers; then one line with how many collections ran and the heap's
# free bytes.
import gc
import time

t0 = time.ticks_ms()
n = 0
junk = []
while time.ticks_diff(time.ticks_ms(), t0) < 200:
    junk.append(bytearray(64))
    if len(junk) > 50:
        junk = []
    gc.collect()
    n += 1
junk = []
gc.collect()
print('{"collections": %d, "free": %d}' % (n, gc.mem_free()))
while True:
    time.sleep_ms(100)
