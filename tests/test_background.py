"""InBackground: calls run in order in one worker thread; an error comes back to the caller."""

from __future__ import annotations

import threading

import pytest

from bpms.io.background import InBackground


def test_calls_run_in_order_in_another_thread():
    done, threads = [], set()
    with InBackground(depth=1) as later:
        for k in range(20):
            later.submit(lambda k=k: (done.append(k), threads.add(threading.get_ident())))
    assert done == list(range(20))
    assert threads and threading.get_ident() not in threads


def test_an_error_is_raised_in_the_caller_and_stops_the_rest():
    ran = []

    def fail() -> None:
        raise OSError("disk full")

    later = InBackground()
    later.submit(fail)
    later.submit(ran.append, 1)  # may be queued before the failure is known: not run
    with pytest.raises(OSError, match="disk full"):
        later.close()
    assert ran == []


def test_the_callers_own_error_goes_first():
    with pytest.raises(KeyError), InBackground() as later:
        later.submit(lambda: None)
        raise KeyError("mine")
