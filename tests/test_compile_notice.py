"""A first run of the fast engine compiles its code for up to a minute: it says so, and keeps
saying how long it has been compiling until the first steps are done (a new user saw nothing
move for that minute and could not tell a compile from a hang)."""

import threading
import time

from snn_fg.backends.fast.backend import still_compiling


def test_it_says_how_long_it_has_been_compiling_until_told_to_stop():
    said, lock = [], threading.Lock()

    def say(line):
        with lock:
            said.append((time.perf_counter(), line))

    t0 = time.perf_counter()
    done = still_compiling(say, every_s=0.05)
    time.sleep(0.28)
    done.set()
    stopped = time.perf_counter()
    time.sleep(0.2)
    with lock:
        lines = list(said)
    assert len(lines) >= 3
    assert all(line.startswith("still compiling the fast engine's code (") for _, line in lines)
    assert all(t <= stopped + 0.01 for t, _ in lines)  # (nothing once told to stop)
    assert all(t - t0 >= 0.045 for t, _ in lines)  # (the first line after one interval, not at once)
