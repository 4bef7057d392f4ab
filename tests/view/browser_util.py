"""What the browser tests share: failing with one line, and waiting for a condition."""
import sys
import time


def fail(msg):
    print("FAIL:", msg, flush=True)
    sys.exit(1)


def wait_for(what, fn, timeout=20.0, every=0.1):
    end = time.time() + timeout
    while True:
        value = fn()
        if value:
            return value
        if time.time() > end:
            fail("timed out waiting for " + what)
        time.sleep(every)
