"""Pieces the API benchmarks share: the demo session's files, an open-loop read load and latency rows.

Used by :mod:`benchmarks.api_upload`, :mod:`benchmarks.api_load` and :mod:`benchmarks.load`.

* :func:`demo_session` — the 24 MetaBase files of the demo session, as ``chakamo demo`` simulates it;
* :func:`open_loop_get` — ``rate`` GET requests per second for ``seconds`` seconds, each sent at its scheduled
  time whether or not the earlier ones have answered (open loop), so a slow server cannot slow the load down
  and hide its own latency (the "coordinated omission" of closed-loop generators); a lean HTTP/1.1 client of
  its own (:class:`_Http11`), so that what it reports is the server's time, not the client's;
* :func:`latency_row` — one markdown row ``| name | n | p50 | p95 | p99 | max | non-200 |`` in milliseconds;
* :func:`tree_cpu_s` — the CPU seconds of the server process and of its helper processes (Linux).
"""

from __future__ import annotations

import asyncio
import time
from pathlib import Path
from typing import NamedTuple
from urllib.parse import urlsplit

import numpy as np

#: the header of the table whose rows :func:`latency_row` prints
LATENCY_HEADER = ("| endpoint | n | p50 (ms) | p95 (ms) | p99 (ms) | max (ms) | non-200 |\n"
                  "| --- | ---: | ---: | ---: | ---: | ---: | ---: |")


def demo_session(folder: Path, seed: int = 7) -> list[Path]:
    """The demo session's 24 MetaBase files, simulated as `chakamo demo` does (10 step-up cycles); another ``seed``
    gives another patient's session (other noise, biases, mounting and motion: every file's content differs)."""
    from app.pipeline.demo import simulate_session, write_session

    write_session(folder, simulate_session(seed=seed, side="right", n_cycles=10))
    return sorted(folder.glob("*.csv"))


class Read(NamedTuple):
    """One GET of :func:`open_loop_get`."""

    path: str
    ms: float  # from its scheduled time to its answer's last byte
    status: int  # -1: no answer (refused, reset, timed out)
    late_ms: float  # how long after its scheduled time the client began to send it (the client's own delay)


class _Http11:
    """The open loop's HTTP/1.1 client: GETs on ``asyncio`` streams, keep-alive connections reused last in first
    out, a new connection whenever none is idle (no pool limit, so no request waits in the client for a
    connection).

    Why not httpx: under a server backlog of a few hundred requests, httpx's asynchronous pool spent seconds of
    its own per request on the 2-core machine: during the 20-clinician burst of :mod:`benchmarks.load` it reported
    ``/healthz`` at p50 6.1 s / p95 17 s while a sequential ``curl`` of ``/healthz`` in the same run answered p50
    4 ms / p95 51 ms, and the server's own timing of its GETs (an ASGI wrapper) said p50 27 ms / p95 342 ms for
    the job polls.  This client only writes a request line and reads the answer by its ``Content-Length`` (or its
    chunks, or to the end of the connection)."""

    def __init__(self, base: str, headers: dict, timeout_s: float) -> None:
        url = urlsplit(base)
        self._host, self._port = url.hostname or "127.0.0.1", url.port or 80
        self._headers = "".join(f"{k}: {v}\r\n" for k, v in headers.items())
        self._timeout_s = timeout_s
        self._idle: list[tuple[asyncio.StreamReader, asyncio.StreamWriter]] = []

    async def get(self, path: str, on_send) -> int:
        """The status of ``GET path`` (-1 without an answer); ``on_send()`` is called as the request is written."""
        try:
            return await asyncio.wait_for(self._get(path, on_send), self._timeout_s)
        except (OSError, EOFError, ValueError, IndexError, asyncio.TimeoutError, asyncio.IncompleteReadError,
                asyncio.LimitOverrunError):  # IndexError: a malformed status line
            return -1

    async def _get(self, path: str, on_send) -> int:
        request = f"GET {path} HTTP/1.1\r\nHost: {self._host}:{self._port}\r\n{self._headers}\r\n".encode("latin-1")
        sent = False
        while True:
            if not sent:  # the client's own delay ends here; connecting is part of the answer's time
                on_send()
                sent = True
            reused = bool(self._idle)
            reader, writer = self._idle.pop() if reused else await asyncio.open_connection(self._host, self._port)
            try:
                writer.write(request)
                head = await reader.readuntil(b"\r\n\r\n")
            except (OSError, asyncio.IncompleteReadError):
                writer.close()
                if reused:  # an idle connection the server had closed (its keep-alive timeout): try a new one
                    continue
                raise
            except BaseException:
                writer.close()
                raise
            break
        try:
            status, keep = await _read_body(reader, head)
        except BaseException:
            writer.close()
            raise
        if keep:
            self._idle.append((reader, writer))
        else:
            writer.close()
        return status

    def close(self) -> None:
        for _, writer in self._idle:
            writer.close()
        self._idle.clear()


async def _read_body(reader: asyncio.StreamReader, head: bytes) -> tuple[int, bool]:
    """Read the body the response ``head`` announces; ``(status, whether the connection may be reused)``."""
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split(" ", 2)[1])
    fields = {k.strip().lower(): v.strip().lower() for k, _, v in (ln.partition(":") for ln in lines[1:] if ln)}
    keep = fields.get("connection") != "close"
    if status in (204, 304) or 100 <= status < 200:  # no body by definition (RFC 9112 §6.3)
        pass
    elif "chunked" in fields.get("transfer-encoding", ""):
        while True:
            size = int((await reader.readuntil(b"\r\n")).split(b";")[0], 16)
            if size == 0:
                while await reader.readuntil(b"\r\n") != b"\r\n":  # trailers, then the blank line
                    pass
                break
            await reader.readexactly(size + 2)
    elif "content-length" in fields:
        await reader.readexactly(int(fields["content-length"]))
    else:  # delimited by the end of the connection
        await reader.read()
        keep = False
    return status, keep


async def _open_loop(base: str, headers: dict, paths: list[str], rate: float, seconds: float,
                     timeout_s: float) -> list[Read]:
    out: list[Read] = []
    client = _Http11(base, headers, timeout_s)

    async def one(path: str, due: float) -> None:
        left = [due]
        status = await client.get(path, lambda: left.__setitem__(0, time.perf_counter()))
        out.append(Read(path, (time.perf_counter() - due) * 1000, status, (left[0] - due) * 1000))

    tasks = []
    t0 = time.perf_counter()
    try:
        for i in range(int(rate * seconds)):
            due = t0 + i / rate
            delay = due - time.perf_counter()
            if delay > 0:
                await asyncio.sleep(delay)
            tasks.append(asyncio.create_task(one(paths[i % len(paths)], due)))
        await asyncio.gather(*tasks)
    finally:
        client.close()
    return out


def open_loop_get(base: str, headers: dict, paths: list[str], rate: float, seconds: float,
                  timeout_s: float = 30.0) -> list[Read]:
    """The :class:`Read` of each of ``int(rate * seconds)`` GETs cycling over ``paths`` (module docstring).

    Each request's latency counts from its scheduled time, so a client that falls behind adds its delay to the
    figures rather than hiding it; ``late_ms`` says how much of it was the client's (:func:`latency_table` prints
    it).  Bounded: the last request leaves after ``seconds`` and every request gives up after ``timeout_s``.  Runs
    its own event loop, so it may be called from a thread or a child process (``benchmarks.load`` does the
    latter, so the clients' threads there cannot delay it through the GIL).  The loop runs in a thread of its own,
    so a caller whose thread already runs an event loop (e.g. a test session holding Playwright's) is no
    obstacle."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="open-loop") as pool:
        return pool.submit(asyncio.run, _open_loop(base, headers, paths, rate, seconds, timeout_s)).result()


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


def latency_table(results: list[Read], paths: list[str]) -> str:
    """The per-endpoint and overall table of :func:`open_loop_get`'s ``results`` (non-200 counted as bad), and a
    line on the client's own delay in sending (its ``late_ms``): when that is not small against the latencies,
    the client, not the server, is what was measured."""
    lines = [LATENCY_HEADER]
    for path in paths:
        rows = [r for r in results if r.path == path]
        lines.append(latency_row(path, np.array([r.ms for r in rows]), sum(r.status != 200 for r in rows)))
    lines.append(latency_row("**all**", np.array([r.ms for r in results]), sum(r.status != 200 for r in results)))
    if results:
        late = np.percentile([r.late_ms for r in results], [50, 95, 100])
        lines.append(f"\nthe client sent each request after its scheduled time by p50 {late[0]:.1f} / p95 {late[1]:.1f} / "
                     f"max {late[2]:.1f} ms (included in the latencies above)")
    return "\n".join(lines)


__all__ = ["LATENCY_HEADER", "Read", "demo_session", "latency_row", "latency_table", "open_loop_get"]
