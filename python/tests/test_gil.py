"""Stepping releases the GIL: two threads stepping two simulations run at the same time."""

from __future__ import annotations

import threading
import time

import jello
from conftest import EXAMPLES


def test_two_threads_stepping_overlap() -> None:
    # Thread A makes one long step call; thread B makes short ones and counts those it finishes
    # while A's call is under way. Were the GIL held through a call, B could run no Python
    # between A's flag and A's return (one switch at most).
    long_run = jello.load(EXAMPLES / "jello.w")
    short_runs = jello.load(EXAMPLES / "rotate.w")
    a_started = threading.Event()
    a_done = threading.Event()
    overlapping = 0

    def a() -> None:
        a_started.set()
        long_run.step(4000)
        a_done.set()

    def b() -> None:
        nonlocal overlapping
        a_started.wait()
        while not a_done.is_set():
            short_runs.step(5)
            if not a_done.is_set():
                overlapping += 1

    threads = [threading.Thread(target=a), threading.Thread(target=b)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert long_run.steps == 4000
    assert overlapping > 10


def test_python_threads_run_while_stepping() -> None:
    sim = jello.load(EXAMPLES / "jello.w")
    ticks = 0
    done = threading.Event()

    def count() -> None:
        nonlocal ticks
        while not done.is_set():
            ticks += 1
            time.sleep(0.0005)

    counter = threading.Thread(target=count)
    counter.start()
    time.sleep(0.01)
    before = ticks
    sim.step(4000)
    during = ticks - before
    done.set()
    counter.join()
    # Holding the GIL for the whole call would allow a tick or two at its edges.
    assert during > 20


def test_ctrl_c_stops_a_long_step_call_between_steps() -> None:
    # In a child process, SIGINT a second into a call of ten million steps (about a quarter of
    # an hour): KeyboardInterrupt comes at a whole step, the state sound.
    import subprocess
    import sys

    script = """
import os, signal, threading
import numpy as np
import jello
signal.signal(signal.SIGINT, signal.default_int_handler)
sim = jello.load(%r)
threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
try:
    sim.step(10_000_000)
except KeyboardInterrupt:
    print(sim.steps, bool(np.isfinite(sim.positions).all()))
""" % str(EXAMPLES / "jello.w")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    # Had it not stopped, the call would have outlived the timeout many times over.
    steps, finite = run.stdout.split()
    assert 0 < int(steps) < 10_000_000 and finite == "True"
