"""Latency of the non-processing endpoints at a steady 50 requests/s (goal p95 < 50 ms).

``python -m benchmarks.api_load [--rate 50] [--seconds 20]``

A real uvicorn server in a child process on 127.0.0.1 (:func:`benchmarks.api_upload.running_server`, a
temporary data dir) holds one processed demo session.  An open-loop generator
(:func:`benchmarks.http_load.open_loop_get`: asyncio, HTTP/1.1 keep-alive) then sends ``rate`` requests per second for
``seconds`` seconds — each request leaves at its scheduled time whether or not earlier ones have answered, so
a slow server cannot slow the load down — cycling over the endpoints a UI page or a hospital system polls:
patient list and search, patient, session, job, results.json, the trend, ``/auth/me`` and ``/healthz``.
Printed: per endpoint and overall, count, p50, p95, p99 and max latency (ms) and any non-200 answers.
Bounded in time; loopback only.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

from benchmarks.api_upload import one_run, running_server
from benchmarks.http_load import demo_session, latency_table, open_loop_get


def main(argv: list[str] | None = None) -> int:
    import httpx

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=50.0, help="requests per second (default 50)")
    parser.add_argument("--seconds", type=float, default=20.0, help="duration (default 20 s)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        files = demo_session(Path(tmp) / "session")
        with running_server(Path(tmp) / "data") as (base, headers):
            with httpx.Client(base_url=base, timeout=120) as client:
                one_run(client, headers, files, 0)  # one processed session to read
                session = client.get("/api/v1/patients/1/sessions", headers=headers).json()[0]
                job_id = client.get(f"/api/v1/sessions/{session['id']}", headers=headers).json()["jobs"][0]["id"]
            sid = session["id"]
            paths = ["/api/v1/patients", "/api/v1/patients?q=bench", "/api/v1/patients/1", f"/api/v1/sessions/{sid}",
                     f"/api/v1/jobs/{job_id}", f"/api/v1/sessions/{sid}/results", "/api/v1/patients/1/trend",
                     "/api/v1/auth/me", "/healthz"]
            results = open_loop_get(base, headers, paths, args.rate, args.seconds)
    print(f"API latency at {args.rate:g} requests/s for {args.seconds:g} s (real uvicorn on loopback, open loop; "
          "goal p95 < 50 ms)\n")
    print(latency_table(results, paths))
    load = os.getloadavg()[0]
    print(f"\n1-minute load average at the end: {load:.1f} on {os.cpu_count()} CPUs (client and server share them; "
          "the machine is shared: re-run when it is quiet to compare)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
