"""Stage times of one command, for ``benchmarks/cold.py``: with ``CHAKAMO_TIMINGS=1`` in the environment every
finished stage writes one line on stderr, ::

    chakamo-timing: <stage> <seconds>

``<stage>`` is a word (``imports``, ``read``, ``pipeline``, ``reports``, ``write``, ``total``, or a finer one such
as ``report.pdf``), followed by its wall and CPU seconds (``time.perf_counter``, ``time.process_time``); a stage
printed several times is summed by the reader.  Without the variable nothing is
printed and :func:`stage` costs one check.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

ENV = "CHAKAMO_TIMINGS"


def enabled() -> bool:
    return os.environ.get(ENV) == "1"


def report(name: str, seconds: float, cpu_s: float | None = None) -> None:
    """Print one stage time (when enabled): wall seconds, then CPU seconds when known."""
    if enabled():
        cpu = "" if cpu_s is None else f" {cpu_s:.6f}"
        print(f"chakamo-timing: {name} {seconds:.6f}{cpu}", file=sys.stderr, flush=True)


def pss_mb() -> float | None:
    """This process's proportional set size now, MB (Linux ``/proc/self/smaps_rollup``; None elsewhere): its
    resident memory with each page shared with other processes (a fork's, a library's) divided among them,
    so that the PSS of several processes adds up to the memory they hold together."""
    try:
        with open("/proc/self/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def report_process(process: str, peak_rss_mb: float, cpu_s: float) -> None:
    """Print one process's peak resident memory, CPU time and current PSS (when enabled), ::

        chakamo-process: <process> <peak_rss_mb> <cpu_s> [<pss_mb>]

    (the parent's rusage shows only the largest of its processes' peaks, not what they held together, and
    their CPU summed, not how it overlapped)."""
    if enabled():
        pss = pss_mb()
        tail = "" if pss is None else f" {pss:.1f}"
        print(f"chakamo-process: {process} {peak_rss_mb:.1f} {cpu_s:.6f}{tail}", file=sys.stderr, flush=True)


@contextmanager
def stage(name: str) -> Iterator[None]:
    """Time the block as stage ``name``."""
    if not enabled():
        yield
        return
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        yield
    finally:
        report(name, time.perf_counter() - t0, time.process_time() - c0)
