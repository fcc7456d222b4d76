"""A clinician's reads while an anonymous flood of parallel logins hits the server (issue 16 finding 2; goal:
reads p95 < 100 ms).

``python -m benchmarks.login_flood [--logins 120] [--seconds 10] [--rate 20] [--addresses 1]``

A real uvicorn server in a child process on 127.0.0.1 (:func:`benchmarks.api_upload.running_server`: the embedded
default — SQLite, in-process job threads — in a temporary data dir) holds one patient.  For ``seconds``
seconds:

* a clinician (a clinician API token) reads the patient list and the patient at ``rate`` requests per second,
  open loop (:func:`benchmarks.http_load.open_loop_get`: each read leaves at its scheduled time whether or not
  the earlier ones answered, so a slow server cannot hide its latency);
* ``logins`` anonymous clients (in a child process, so that their event loop cannot delay the reads' through
  the GIL) each send ``POST /auth/login`` with a wrong password for an email of their own
  and send the next one as soon as the answer arrives (a sustained flood of ``logins`` parallel logins).  With
  ``--addresses N`` the clients are spread over N loopback source addresses (127.0.0.2 …), so the per-address
  cap does not refuse them all and the server-wide queue bound is what is measured.

Printed: the reads' count, p50/p95/p99/max (ms) and non-200 answers, the logins' answers by status code and
their latency, and the machine's load.  Bounded in time (every request gives up after 30 s); loopback only.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import tempfile
import multiprocessing
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from benchmarks.api_upload import running_server
from benchmarks.http_load import LATENCY_HEADER, latency_row, open_loop_get


async def _flood(base: str, n: int, seconds: float, addresses: int) -> list[tuple[int, float]]:
    """``(status, latency_ms)`` of every login of ``n`` closed-loop clients over ``seconds`` (-1: no answer)."""
    import httpx

    out: list[tuple[int, float]] = []
    clients = []
    for a in range(max(1, addresses)):
        transport = httpx.AsyncHTTPTransport(local_address=f"127.0.0.{2 + a}" if addresses > 1 else None)
        clients.append(httpx.AsyncClient(base_url=base, timeout=30, transport=transport,
                                         limits=httpx.Limits(max_connections=n, max_keepalive_connections=n)))
    end = time.perf_counter() + seconds

    async def one(i: int) -> None:
        client = clients[i % len(clients)]
        k = 0
        while time.perf_counter() < end:
            k += 1
            t = time.perf_counter()
            try:
                r = await client.post("/api/v1/auth/login",
                                      json={"email": f"flood{i}-{k}@nowhere.test", "password": "not the password"})
                status = r.status_code
            except httpx.HTTPError:
                status = -1
            out.append((status, (time.perf_counter() - t) * 1000))
            if status in (429, 503):  # refused at once: a real client would back off a little
                await asyncio.sleep(0.05)

    try:
        await asyncio.gather(*(one(i) for i in range(n)))
    finally:
        for c in clients:
            await c.aclose()
    return out


def _noop() -> None:
    return None


def flood_process(base: str, n: int, seconds: float, addresses: int) -> list[tuple[int, float]]:
    """:func:`_flood` on an event loop of its own (the child process' entry point)."""
    return asyncio.run(_flood(base, n, seconds, addresses))


def run(logins: int, seconds: float, rate: float, addresses: int) -> tuple[list, list, list[str]]:
    """The reads (:class:`benchmarks.http_load.Read`), the logins ``(status, ms)`` and the read paths of one flood."""
    import httpx

    with tempfile.TemporaryDirectory() as tmp, running_server(Path(tmp) / "data") as (base, headers):
        r = httpx.post(base + "/api/v1/patients", json={"external_id": "FLOOD-1", "side": "right"}, headers=headers)
        r.raise_for_status()
        paths = ["/api/v1/patients", f"/api/v1/patients/{r.json()['id']}"]
        open_loop_get(base, headers, paths, 5, 1.0)  # warm the routes (each call opens its own connections)
        # the flood runs in a child process: its event loop must not delay the reads' one through the GIL
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            pool.submit(_noop).result()  # the child is up before the clock starts
            fut = pool.submit(flood_process, base, logins, seconds + 1.0, addresses)
            time.sleep(0.5)  # the flood is on before the first read
            reads = open_loop_get(base, headers, paths, rate, seconds)
            flood = fut.result()
    return reads, flood, paths


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logins", type=int, default=120, help="parallel anonymous logins (default 120)")
    parser.add_argument("--seconds", type=float, default=10.0, help="duration of the reads (default 10 s)")
    parser.add_argument("--rate", type=float, default=20.0, help="clinician reads per second (default 20)")
    parser.add_argument("--addresses", type=int, default=1,
                        help="loopback source addresses the logins come from (default 1)")
    args = parser.parse_args(argv)
    if not 1 <= args.logins <= 1000 or not 0 < args.seconds <= 120 or not 1 <= args.addresses <= 250:
        parser.error("keep it bounded: 1..1000 logins, at most 120 s, 1..250 addresses")
    reads, flood, paths = run(args.logins, args.seconds, args.rate, args.addresses)
    print(f"Clinician reads at {args.rate:g}/s for {args.seconds:g} s during {args.logins} parallel anonymous logins "
          f"from {args.addresses} address(es) (real uvicorn on loopback, embedded default; goal reads p95 < 100 ms)\n")
    print(LATENCY_HEADER)
    ms = np.array([r.ms for r in reads])
    print(latency_row("clinician reads (all)", ms, sum(r.status != 200 for r in reads)))
    for p in paths:
        sel = [r for r in reads if r.path == p]
        print(latency_row(f"`GET {p}`", np.array([r.ms for r in sel]), sum(r.status != 200 for r in sel)))
    lat = np.array([m for _, m in flood])
    print(latency_row("anonymous logins", lat, sum(s != 401 for s, _ in flood)))
    counts = Counter(s for s, _ in flood)
    print("\nlogin answers: " + ", ".join(f"{k}: {v}" for k, v in sorted(counts.items())))
    print(f"\n1-minute load average at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs (client and server "
          "share them; the machine is shared: re-run when it is quiet to compare)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
