"""Threads seen from /proc: the CPU ticks that other threads use (Linux), to catch a BLAS worker spinning."""

import os
import threading
import time


def other_threads_cpu_ticks():
    """CPU clock ticks (user + system) used so far by this process's threads other than the
    calling one, from /proc/self/task (Linux)."""
    me = threading.get_native_id()
    total = 0
    for task in os.listdir("/proc/self/task"):
        if int(task) == me:
            continue
        try:
            with open(f"/proc/self/task/{task}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of stat)
    return total


def ticks_of_other_threads_after(call, window=0.15):
    """Clock ticks (1/100 s) that other threads of this process use in the `window` seconds
    after call() returns, while this thread sleeps: about 100 * window when a BLAS worker spins,
    0 when nothing else runs. Counted per thread, so other processes loading the machine do not
    blur it as a wall-clock measure would."""
    time.sleep(0.3)  # let any worker from earlier calls go to sleep
    call()
    before = other_threads_cpu_ticks()
    time.sleep(window)
    return other_threads_cpu_ticks() - before
