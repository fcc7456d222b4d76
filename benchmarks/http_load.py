"""Pieces the API benchmarks share: the demo session's files, an open-loop read load and latency rows.

Used by :mod:`benchmarks.api_upload`, :mod:`benchmarks.api_load` and :mod:`benchmarks.load`.

* :func:`demo_session` — the 24 MetaBase files of the demo session, as ``chakamo demo`` simulates it;
* :func:`open_loop_get` — ``rate`` GET requests per second for ``seconds`` seconds, each sent at its scheduled
  time whether or not the earlier ones have answered (open loop), so a slow server cannot slow the load down
  and hide its own latency (the "coordinated omission" of closed-loop generators);
* :func:`latency_row` — one markdown row ``| name | n | p50 | p95 | p99 | max | non-200 |`` in milliseconds;
* :func:`tree_cpu_s` — the CPU seconds of the server process and of its helper processes (Linux).
"""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import numpy as np

#: the header of the table whose rows :func:`latency_row` prints
LATENCY_HEADER = ("| endpoint | n | p50 (ms) | p95 (ms) | p99 (ms) | max (ms) | non-200 |\n"
                  "| --- | ---: | ---: | ---: | ---: | ---: | ---: |")


def demo_session(folder: Path) -> list[Path]:
    """The demo session's 24 MetaBase files, simulated as `chakamo demo` does (10 step-up cycles)."""
    from app.pipeline.demo import simulate_session, write_session

    write_session(folder, simulate_session(seed=7, side="right", n_cycles=10))
    return sorted(folder.glob("*.csv"))


async def _open_loop(base: str, headers: dict, paths: list[str], rate: float,
                     seconds: float) -> list[tuple[str, float, int]]:
    import httpx

    out: list[tuple[str, float, int]] = []
    limits = httpx.Limits(max_connections=200, max_keepalive_connections=50)
    async with httpx.AsyncClient(base_url=base, headers=headers, timeout=30, limits=limits) as client:
        async def one(path: str) -> None:
            t = time.perf_counter()
            try:
                status = (await client.get(path)).status_code
            except httpx.HTTPError:
                status = -1
            out.append((path, (time.perf_counter() - t) * 1000, status))

        tasks = []
        t0 = time.perf_counter()
        for i in range(int(rate * seconds)):
            delay = t0 + i / rate - time.perf_counter()
            if delay > 0:
                await asyncio.sleep(delay)
            tasks.append(asyncio.create_task(one(paths[i % len(paths)])))
        await asyncio.gather(*tasks)
    return out


def open_loop_get(base: str, headers: dict, paths: list[str], rate: float,
                  seconds: float) -> list[tuple[str, float, int]]:
    """``(path, latency_ms, status)`` of ``int(rate * seconds)`` GETs cycling over ``paths`` (module docstring).

    ``status`` is -1 when the request failed without an answer (refused, reset, 30 s timeout).  Bounded: the
    last request leaves after ``seconds`` and every request gives up after 30 s.  Runs its own event loop, so
    it may be called from a thread or a child process (``benchmarks.load`` does the latter, so the clients'
    threads there cannot delay it through the GIL).  The loop runs in a thread of its own, so a caller whose
    thread already runs an event loop (e.g. a test session holding Playwright's) is no obstacle."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="open-loop") as pool:
        return pool.submit(asyncio.run, _open_loop(base, headers, paths, rate, seconds)).result()


def tree_cpu_s(pid: int) -> tuple[float, float] | None:
    """CPU seconds (user + system) used so far by process ``pid`` and by its live child processes together (the
    server and its helpers), from ``/proc``; None where there is no ``/proc`` (not Linux) or ``pid`` is gone."""
    import os

    def own(p: int) -> float:
        with open(f"/proc/{p}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    try:
        server = own(pid)
        helpers = 0.0
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    with open(f"/proc/{entry}/stat") as f:
                        if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                            helpers += own(int(entry))
                except (OSError, ValueError, IndexError):
                    continue
    except (OSError, ValueError, IndexError):
        return None
    return server, helpers


def latency_row(name: str, ms: np.ndarray, bad: int) -> str:
    """``| name | n | p50 | p95 | p99 | max | bad |`` of latencies ``ms`` (milliseconds); dashes when empty."""
    if len(ms) == 0:
        return f"| {name} | 0 | – | – | – | – | {bad} |"
    p50, p95, p99 = np.percentile(ms, [50, 95, 99])
    return f"| {name} | {len(ms)} | {p50:.1f} | {p95:.1f} | {p99:.1f} | {ms.max():.1f} | {bad} |"


def latency_table(results: list[tuple[str, float, int]], paths: list[str]) -> str:
    """The per-endpoint and overall table of :func:`open_loop_get`'s ``results`` (non-200 counted as bad)."""
    lines = [LATENCY_HEADER]
    for path in paths:
        rows = [(ms, st) for p, ms, st in results if p == path]
        lines.append(latency_row(path, np.array([ms for ms, _ in rows]), sum(st != 200 for _, st in rows)))
    lines.append(latency_row("**all**", np.array([ms for _, ms, _ in results]), sum(st != 200 for *_, st in results)))
    return "\n".join(lines)


__all__ = ["LATENCY_HEADER", "demo_session", "latency_row", "latency_table", "open_loop_get"]
