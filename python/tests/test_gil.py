"""Stepping releases the GIL: other Python threads run, and step other simulations, while a call
of `step` is under way.

Whether a call is under way is an event, not a time: while `step` runs, its simulation is
borrowed mutably by the native module, so reading it from another thread raises RuntimeError
("Already mutably borrowed"). That can only be seen from a thread that runs Python while the
call is in progress, which it could not if the call held the GIL; no test here measures time.
"""

from __future__ import annotations

import threading

import jello
from conftest import EXAMPLES


def in_a_call(sim: jello.Simulation) -> bool:
    """True when another thread is inside a call on `sim` (its native object is borrowed)."""
    try:
        sim.steps
    except RuntimeError as e:
        assert "borrowed" in str(e), e
        return True
    return False


def test_the_borrow_shows_a_call_under_way() -> None:
    # The probe itself: false outside any call, true during one.
    sim = jello.load(EXAMPLES / "jello.w")
    assert not in_a_call(sim)
    seen = threading.Event()
    done = threading.Event()

    def watch() -> None:
        while not done.is_set():
            if in_a_call(sim):
                seen.set()
                return

    watcher = threading.Thread(target=watch)
    watcher.start()
    sim.step(20_000)
    done.set()
    watcher.join()
    assert seen.is_set()
    assert not in_a_call(sim)


def test_two_threads_stepping_overlap() -> None:
    # Thread A makes one long call; the main thread makes short ones and counts those that
    # began and ended while A's call was under way (its simulation borrowed before and after).
    long_run = jello.load(EXAMPLES / "jello.w")
    short_runs = jello.load(EXAMPLES / "rotate.w")
    a_started = threading.Event()

    def a() -> None:
        a_started.set()
        long_run.step(20_000)

    thread = threading.Thread(target=a)
    thread.start()
    a_started.wait()
    inside = 0
    while thread.is_alive() and inside < 5:
        before = in_a_call(long_run)
        short_runs.step(5)
        if before and in_a_call(long_run):
            inside += 1
    thread.join()
    assert long_run.steps == 20_000
    assert inside >= 1, "no short call ran while the long one was under way"


def test_python_threads_run_while_stepping() -> None:
    # A thread doing plain Python work sees the call under way, and keeps counting through it.
    sim = jello.load(EXAMPLES / "jello.w")
    done = threading.Event()
    ticks_inside = 0

    def count() -> None:
        nonlocal ticks_inside
        while not done.is_set():
            if in_a_call(sim):
                ticks_inside += 1
                if ticks_inside >= 3:
                    return

    counter = threading.Thread(target=count)
    counter.start()
    sim.step(20_000)
    done.set()
    counter.join()
    # Holding the GIL for the whole call, the counter could not run Python during it at all.
    assert ticks_inside >= 1


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
