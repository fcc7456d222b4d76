"""Waiting for a helper process (of a ``ProcessPoolExecutor``) to end, as the tests that stop one need."""

from __future__ import annotations

import time
from multiprocessing.connection import wait


def ended(proc, timeout_s: float = 60.0):
    """``proc``'s exit code once it has ended.  Waits on the process' sentinel, not ``Process.join``: the
    executor's own thread also joins its workers, and when it reaps the child first this thread's join returns
    with ``exitcode`` still None (CPython 3.11's ``Popen.poll`` answers None on ECHILD) until that thread
    stores the code."""
    assert wait([proc.sentinel], timeout_s), "the process did not end"
    deadline = time.monotonic() + timeout_s
    while proc.exitcode is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return proc.exitcode
