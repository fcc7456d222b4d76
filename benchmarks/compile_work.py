r"""Compile work: what numba's first compilation of the ``chakamo`` kernels costs, per compiled function.

Usage
-----
``python -m benchmarks.compile_work [--method chakamo] [--top 25]``

The first call of :mod:`benchmarks.speed` (a fresh numba cache) is mostly numba's own front end: type inference
and lowering, in Python.  Its wall time on this two-core machine swings by ±20 % from one run to the next, so a
change of 5 % cannot be seen in it without many runs.  This script counts instead the *Python calls* made while
each function compiled (its own, without the functions it compiled in turn), with ``cProfile``.  The same code
compiles with nearly the same calls whatever the machine's load: the total varies by under 0.5 % between runs of one
tree, a single function's row by up to ~5 % (the offline kernels').  The count leaves out LLVM's share (native
code), so a change it favours is then confirmed on the wall time (:mod:`benchmarks.speed`, old and new trees
alternated).

Numba announces each compilation (``numba:compile`` events), which gives the intervals.  The kernels are compiled in
the main thread, where ``cProfile`` sees them: first a causal 9D call (the shared per-sample kernel), then the
offline 9D call of the speed benchmark (the smoother's other kernels), on the speed benchmark's 1000-sample input.
Compare trees by running this script from each (``PYTHONPATH``) and comparing the totals.
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import os
import pstats
import sys
import tempfile
from typing import Any

from benchmarks.speed import FIRST_CALL_SAMPLES, FS_HZ, simulated_imu


class _Counter:
    """``numba:compile`` listener: Python calls of each compilation, minus those of the compilations it nests."""

    def __init__(self) -> None:
        self.profile = cProfile.Profile()
        self.calls: collections.Counter[str] = collections.Counter()
        self.compiles: collections.Counter[str] = collections.Counter()
        self.enabled = False
        self._stack: list[list[Any]] = []

    def start(self) -> None:
        self.enabled = True
        self.profile.enable()

    def stop(self) -> None:
        self.enabled = False
        self.profile.disable()

    def _total_calls(self) -> int:
        if not self.enabled:  # a compilation outside the measured calls counts nothing
            return 0
        self.profile.disable()
        try:
            return pstats.Stats(self.profile).total_calls
        except TypeError:  # nothing profiled yet
            return 0
        finally:
            self.profile.enable()

    def on_start(self, event: Any) -> None:
        fn = event.data["dispatcher"].py_func
        name = f"{fn.__module__}.{fn.__qualname__}"
        self._stack.append([name, self._total_calls(), 0])

    def on_end(self, event: Any) -> None:
        name, calls0, nested = self._stack.pop()
        calls = self._total_calls() - calls0
        self.calls[name] += calls - nested
        self.compiles[name] += 1
        if self._stack:
            self._stack[-1][2] += calls


def measure(method: str) -> _Counter:
    """Compile ``method``'s kernels (causal 9D, then offline 9D) with a fresh cache, counting per function."""
    if "numba" in sys.modules:
        raise RuntimeError("numba is already imported: its cache folder cannot be changed any more")
    cache = tempfile.TemporaryDirectory(prefix="chakamo-numba-")
    os.environ["NUMBA_CACHE_DIR"] = cache.name
    from numba.core import event

    from estimators.orientation import estimate

    counter = _Counter()

    class Listener(event.Listener):
        def on_start(self, e: Any) -> None:
            counter.on_start(e)

        def on_end(self, e: Any) -> None:
            counter.on_end(e)

    listener = Listener()
    event.register("numba:compile", listener)
    acc, gyr, mag = simulated_imu(FIRST_CALL_SAMPLES)
    counter.start()
    try:
        estimate(acc, gyr, mag, fs_hz=FS_HZ, method=method, offline=False)
        estimate(acc, gyr, mag, fs_hz=FS_HZ, method=method)
    finally:
        counter.stop()
        event.unregister("numba:compile", listener)
        cache.cleanup()
    return counter


def table(counter: _Counter, top: int) -> str:
    width = max([len("function")] + [len(k) for k in counter.calls])
    lines = [f"{'function':<{width}} | {'compiles':>8} | {'Python calls (k)':>16}",
             f"{'-' * width}-|----------|-----------------"]
    for name, calls in counter.calls.most_common(top):
        lines.append(f"{name:<{width}} | {counter.compiles[name]:8d} | {calls // 1000:16d}")
    lines.append(f"{'total (every function)':<{width}} | {sum(counter.compiles.values()):8d} | "
                 f"{sum(counter.calls.values()) // 1000:16d}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--method", default="chakamo")
    parser.add_argument("--top", type=int, default=25, help="functions listed (the total counts them all)")
    args = parser.parse_args(argv)
    print(f"compile work of {args.method!r}: causal 9D, then offline 9D, {FIRST_CALL_SAMPLES} samples, fresh cache",
          flush=True)
    print(table(measure(args.method), args.top))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
