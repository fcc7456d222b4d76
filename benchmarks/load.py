"""N clinicians at once: upload a demo session, process it, poll, download — errors, losses and latencies.

``python -m benchmarks.load [--clinicians 20] [--workers 2] [--backend celery|inprocess] [--read-rate 50]
[--read-seconds 20] [--timeout-s 900] [--same-files]``

Goals (issue 8): 20 concurrent session uploads processed with 0 errors and 0 lost; read endpoints p95 < 50 ms
at 50 requests/s.

What runs (:mod:`benchmarks.load_stack`): the API (``chakamo serve``) and, on ``celery``, PostgreSQL, Redis and
``--workers`` ``chakamo worker --concurrency 1`` processes; on ``inprocess``, SQLite and ``--workers`` job
threads inside the API.  All real subprocesses on loopback, started from nothing and torn down at the end.

What happens:

1. a *reference* session is uploaded and processed first (not in the tables): it warms the server and one
   worker (the first job pays the imports) and gives the read load a processed session to read;
2. ``--clinicians`` threads start together, each one clinician with its own HTTP connection: create a patient
   and a session → upload the 24 files of a demo session of its own (:func:`benchmarks.http_load.demo_session`,
   seed 8, 9, …: every file's content differs, as in a clinic, so every file is placed — renamed and its folder
   synced under the write lock, a new blob row;
   ``--same-files`` gives them all the reference's files, which the blob store then keeps once) in one
   request → request processing → poll the job every :data:`POLL_EVERY_S` s → download ``results`` (JSON) and
   ``report.pdf``.  An upload refused with 503 (more than ``CHAKAMO_MAX_UPLOADS`` at once, the server's
   designed back-pressure: nothing was stored) is retried after its ``Retry-After``, capped at
   :data:`BUSY_WAIT_CAP_S` s so the run stays short; those retries are counted, not taken as errors.  Any
   other unexpected answer, a failed job or a request without an answer is an error, and that clinician stops;
3. the read load runs twice, open loop at ``--read-rate`` for ``--read-seconds`` over the endpoints a UI page
   polls (:func:`benchmarks.http_load.open_loop_get`, in a child process so the clinicians' threads cannot
   delay it through the GIL): *during* — started with the clinicians, so the reads share the CPUs with
   uploads, ingestion checks and processing, the realistic case for a clinic; and *after* every clinician has
   finished, on the idle server, the case :mod:`benchmarks.api_load` measures.  Both are printed because on
   a small machine they differ a lot, and the goal does not say which;
4. verification against the API at the end: each session's stored file count against what was uploaded and
   each job's final status.  *Lost*: an accepted upload whose job never reached done or failed (or that got
   no job), or a session whose stored file count differs from the upload.

Bounded: every wait stops at ``--timeout-s`` after the clinicians started (the unfinished are then lost),
every request gives up after :data:`REQUEST_TIMEOUT_S` s.  The exit status is 1 on any error or loss (usable
as a check); no timing is asserted.  Loopback only.
"""

from __future__ import annotations

import argparse
import os
import random
import tempfile
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from benchmarks.http_load import Read, demo_session, latency_table, open_loop_get, tree_cpu_s
from benchmarks.live_services import Missing
from benchmarks.load_stack import Stack, failure_excerpt, running_stack

PHASES = ("create", "upload", "process request", "job wait", "download", "job poll (one GET)")
#: seconds between two polls of a job by one clinician (a UI polls about this often)
POLL_EVERY_S = 1.0
#: longest wait before retrying an upload refused with 503 (the server says 30 s)
BUSY_WAIT_CAP_S = 5.0
REQUEST_TIMEOUT_S = 120.0


class PhaseError(Exception):
    """A clinician's step went wrong: ``phase`` and what the server (or the connection) said."""

    def __init__(self, phase: str, message: str) -> None:
        super().__init__(f"{phase}: {message}")
        self.phase = phase


@dataclass
class Clinician:
    """What one clinician did and saw; times in seconds."""

    index: int
    patient_id: int | None = None
    session_id: int | None = None
    job_id: int | None = None
    files_uploaded: int = 0  # recordings the accepted upload stored (0: not accepted)
    sha256: set[str] = field(default_factory=set)  # the stored recordings' contents, as the server named them
    busy_retries: int = 0
    phase_s: dict[str, float] = field(default_factory=dict)
    poll_s: list[float] = field(default_factory=list)
    error: PhaseError | None = None
    finished_at: float | None = None  # time.monotonic() after the downloads


def _request(client, phase: str, method: str, path: str, expect: int, **kwargs):
    import httpx

    try:
        r = client.request(method, path, **kwargs)
    except httpx.HTTPError as exc:
        raise PhaseError(phase, f"{method} {path} got no answer ({exc!r})") from None
    if r.status_code != expect:
        raise PhaseError(phase, f"{method} {path} answered {r.status_code}: {r.text[:200]}")
    return r


def _upload(client, c: Clinician, files: list[Path], deadline: float) -> None:
    import httpx

    body = [("files", (p.name, p.read_bytes(), "text/csv")) for p in files]
    path = f"/api/v1/sessions/{c.session_id}/recordings"
    while True:
        try:
            r = client.post(path, files=body)
        except httpx.HTTPError as exc:
            raise PhaseError("upload", f"POST {path} got no answer ({exc!r})") from None
        if r.status_code != 503:
            break
        c.busy_retries += 1
        wait_s = min(float(r.headers.get("Retry-After", BUSY_WAIT_CAP_S)), BUSY_WAIT_CAP_S) * random.uniform(0.5, 1.0)
        if time.monotonic() + wait_s > deadline:
            raise PhaseError("upload", f"still 503 (busy) after {c.busy_retries} tries when the time ran out")
        time.sleep(wait_s)
    if r.status_code != 201 or not r.json()["ingestion"]["ok"]:
        raise PhaseError("upload", f"POST {path} answered {r.status_code}: {r.text[:300]}")
    stored = len(r.json()["recordings"])
    if stored != len(files):  # the answer must list every file sent, not just what the server chose to keep
        raise PhaseError("upload", f"POST {path} stored {stored} of the {len(files)} files sent")
    c.files_uploaded = stored
    c.sha256 = {rec["sha256"] for rec in r.json()["recordings"]}


def run_clinician(c: Clinician, base_url: str, headers: dict, files: list[Path], start: threading.Barrier | None,
                  deadline: float) -> Clinician:
    """One clinician's whole visit (module docstring, step 2); fills ``c`` and never raises."""
    import httpx

    with httpx.Client(base_url=base_url, headers=headers, timeout=REQUEST_TIMEOUT_S) as client:
        if start is not None:
            start.wait()
        phase = "create"
        try:
            t = time.perf_counter()
            c.patient_id = _request(client, phase, "POST", "/api/v1/patients", 201,
                                    json={"external_id": f"LOAD-{c.index:03d}", "side": "right"}).json()["id"]
            c.session_id = _request(client, phase, "POST", f"/api/v1/patients/{c.patient_id}/sessions", 201,
                                    json={"step_height_m": 0.17}).json()["id"]
            c.phase_s[phase] = time.perf_counter() - t
            for phase, step in (("upload", lambda: _upload(client, c, files, deadline)),
                                ("process request", lambda: _process(client, c)),
                                ("job wait", lambda: _wait_job(client, c, deadline)),
                                ("download", lambda: _download(client, c))):
                t = time.perf_counter()
                step()
                c.phase_s[phase] = time.perf_counter() - t
            c.finished_at = time.monotonic()
        except PhaseError as exc:
            c.error = exc
        except Exception as exc:  # noqa: BLE001 — an unexpected answer shape is an error of this clinician too
            c.error = PhaseError(phase, repr(exc))
    return c


def _process(client, c: Clinician) -> None:
    c.job_id = _request(client, "process request", "POST", f"/api/v1/sessions/{c.session_id}/process", 202,
                        json={"lang": "es"}).json()["job_id"]


def _wait_job(client, c: Clinician, deadline: float) -> None:
    while True:
        t = time.perf_counter()
        job = _request(client, "job wait", "GET", f"/api/v1/jobs/{c.job_id}", 200).json()
        c.poll_s.append(time.perf_counter() - t)
        if job["status"] == "done":
            return
        if job["status"] == "failed":
            raise PhaseError("job wait", f"job {c.job_id} failed: {job.get('error')}")
        if time.monotonic() + POLL_EVERY_S > deadline:
            raise PhaseError("job wait", f"job {c.job_id} still {job['status']} when the time ran out")
        time.sleep(POLL_EVERY_S)


def _download(client, c: Clinician) -> None:
    results = _request(client, "download", "GET", f"/api/v1/sessions/{c.session_id}/results", 200).json()
    if not isinstance(results, dict) or not results:
        raise PhaseError("download", f"results of session {c.session_id} are empty")
    pdf = _request(client, "download", "GET", f"/api/v1/sessions/{c.session_id}/report.pdf", 200)
    if not pdf.content.startswith(b"%PDF"):
        raise PhaseError("download", f"report.pdf of session {c.session_id} is not a PDF")


@dataclass
class Summary:
    """What :func:`main` measured; ``exit_status`` 1 when anything went wrong or was lost."""

    clinicians: list[Clinician]
    jobs: dict[str, int]  # done / failed / lost, from the API at the end
    lost: list[str]  # one sentence per loss
    read_during: list[Read]
    read_after: list[Read]
    read_paths: list[str]
    t0: float  # time.monotonic() when the clinicians were released
    wall_s: float  # clinicians released → last one finished

    @property
    def errors(self) -> int:
        return sum(c.error is not None for c in self.clinicians)

    @property
    def read_errors(self) -> int:
        return sum(r.status != 200 for r in self.read_during + self.read_after)

    @property
    def exit_status(self) -> int:
        return 1 if self.errors or self.lost or self.jobs["failed"] or self.read_errors else 0


def verify(stack: Stack, clinicians: list[Clinician]) -> tuple[dict[str, int], list[str]]:
    """Final job statuses and losses, read back from the API (module docstring, step 4)."""
    import httpx

    jobs = {"done": 0, "failed": 0, "lost": 0}
    lost: list[str] = []
    with httpx.Client(base_url=stack.base_url, headers=stack.headers, timeout=REQUEST_TIMEOUT_S) as client:
        for c in clinicians:
            if c.session_id is None:
                continue
            session = client.get(f"/api/v1/sessions/{c.session_id}").json()
            stored = len(session["recordings"])
            if c.files_uploaded and stored != c.files_uploaded:
                lost.append(f"session {c.session_id}: {stored} files stored, {c.files_uploaded} uploaded")
            elif not c.files_uploaded and stored:  # an upload that failed must have stored nothing (all or none)
                lost.append(f"session {c.session_id}: upload failed but {stored} files are stored")
            if not c.files_uploaded:
                continue
            status = client.get(f"/api/v1/jobs/{c.job_id}").json()["status"] if c.job_id is not None else None
            if status in ("done", "failed"):
                jobs[status] += 1
            else:
                jobs["lost"] += 1
                lost.append(f"session {c.session_id}: upload accepted, job {c.job_id} is {status or 'missing'}")
    return jobs, lost


def read_paths(ref: Clinician) -> list[str]:
    """The endpoints a UI page polls, on the reference session, as :mod:`benchmarks.api_load` reads them."""
    pid, sid = ref.patient_id, ref.session_id
    return ["/api/v1/patients", "/api/v1/patients?q=load", f"/api/v1/patients/{pid}", f"/api/v1/sessions/{sid}",
            f"/api/v1/jobs/{ref.job_id}", f"/api/v1/sessions/{sid}/results", f"/api/v1/patients/{pid}/trend",
            "/api/v1/auth/me", "/healthz"]


def sessions(folder: Path, clinicians: int, same_files: bool) -> list[list[Path]]:
    """The files of the reference session (seed 7) and of each clinician's (seed 8, 9, …; the reference's with
    ``same_files``), simulated on every CPU before the clock starts."""
    seeds = [7] if same_files else list(range(7, 8 + clinicians))
    with ProcessPoolExecutor(os.cpu_count(), mp_context=get_context("spawn")) as pool:
        made = list(pool.map(demo_session, [folder / f"session-{s}" for s in seeds], seeds))
    return made if not same_files else made * (clinicians + 1)


def run(stack: Stack, files: list[list[Path]], args: argparse.Namespace) -> Summary:
    """The reference session (``files[0]``), the clinicians (``files[i]``) with the read load during, the read load
    after, verification."""
    ref = run_clinician(Clinician(0), stack.base_url, stack.headers, files[0], None,
                        time.monotonic() + args.timeout_s)
    if ref.error is not None:
        raise RuntimeError(f"the reference session could not be processed ({ref.error}); see the logs above")
    paths = read_paths(ref)
    clinicians = [Clinician(i + 1) for i in range(args.clinicians)]
    barrier = threading.Barrier(args.clinicians + 1)
    with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
        pool.submit(os.getpid).result()  # the child is up before the clock starts
        t0 = time.monotonic()
        deadline = t0 + args.timeout_s
        threads = [threading.Thread(target=run_clinician, daemon=True,
                                    args=(c, stack.base_url, stack.headers, files[c.index], barrier, deadline))
                   for c in clinicians]
        for th in threads:
            th.start()
        barrier.wait()
        during = pool.submit(open_loop_get, stack.base_url, stack.headers, paths, args.read_rate, args.read_seconds)
        for th in threads:
            th.join(max(0.0, deadline - time.monotonic()) + REQUEST_TIMEOUT_S)
        wall_s = max([c.finished_at for c in clinicians if c.finished_at] or [time.monotonic()]) - t0
        read_during = during.result()
    jobs, lost = verify(stack, clinicians)
    read_after = open_loop_get(stack.base_url, stack.headers, paths, args.read_rate, args.read_seconds)
    return Summary(clinicians, jobs, lost, read_during, read_after, paths, t0, wall_s)


def _phase_row(name: str, seconds: list[float], errors: int | None) -> str:
    err = "–" if errors is None else errors
    if not seconds:
        return f"| {name} | 0 | {err} | – | – | – |"
    p50, p95 = np.percentile(seconds, [50, 95])
    return f"| {name} | {len(seconds)} | {err} | {p50:.3f} | {p95:.3f} | {max(seconds):.3f} |"


def print_tables(s: Summary, stack: Stack, args: argparse.Namespace) -> None:
    """The tables of the module docstring, markdown, on stdout."""
    n = len(s.clinicians)
    what = "the same files (stored once)" if args.same_files else "a session of their own each"
    print(f"\nLoad: {n} clinicians at once uploading {what}, backend {stack.backend} ({stack.describe}); loopback\n")
    print("| phase | n | errors | p50 (s) | p95 (s) | max (s) |\n| --- | ---: | ---: | ---: | ---: | ---: |")
    for phase in PHASES:
        samples = ([t for c in s.clinicians for t in c.poll_s] if phase.startswith("job poll")
                   else [c.phase_s[phase] for c in s.clinicians if phase in c.phase_s])
        # a failed poll ends its clinician's "job wait": its error is counted there, not per poll
        errors = None if phase.startswith("job poll") else sum(c.error is not None and c.error.phase == phase
                                                                  for c in s.clinicians)
        print(_phase_row(phase, samples, errors))
    busy = sum(c.busy_retries for c in s.clinicians)
    overlap = sum(c.finished_at is not None and c.finished_at - s.t0 <= args.read_seconds for c in s.clinicians)
    print(f"\nclinicians finished within the first read window ({args.read_seconds:g} s): {overlap} of {n}")
    print(f"uploads refused with 503 (busy, retried after ≤ {BUSY_WAIT_CAP_S:g} s): {busy}; "
          f"job polls every {POLL_EVERY_S:g} s (job wait resolution)")
    done = s.jobs["done"]
    print("\n| jobs | done | failed | lost | errors | sessions per minute | wall time (s) |\n"
          "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    print(f"| {n} | {done} | {s.jobs['failed']} | {len(s.lost)} | {s.errors} | {60.0 * done / s.wall_s:.1f} | "
          f"{s.wall_s:.1f} |")
    for c in s.clinicians:
        if c.error is not None:
            print(f"- error, clinician {c.index}: {c.error}")
    for line in s.lost:
        print(f"- lost: {line}")
    for title, results in (("during the clinicians' run (sharing the CPUs with uploads and processing)",
                            s.read_during), ("after it, on the idle server", s.read_after)):
        print(f"\nRead endpoints {title}: {args.read_rate:g} requests/s for {args.read_seconds:g} s, open loop "
              "(goal p95 < 50 ms)\n")
        print(latency_table(results, s.read_paths))
    cpu = tree_cpu_s(stack.api.proc.pid)
    if cpu is not None:
        print(f"\nCPU used by the API process since it started: {cpu[0]:.1f} s; by its live helper processes (job, "
              f"check): {cpu[1]:.1f} s")
    print(f"\n1-minute load average at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs (client, API, "
          "workers and databases share them, and the machine is shared: numbers are noisy)")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--clinicians", type=int, default=20, help="clinicians uploading at once (default 20)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (celery) or job threads (inprocess)")
    p.add_argument("--backend", choices=("celery", "inprocess"), default="celery", help="job engine (default celery)")
    p.add_argument("--read-rate", type=float, default=50.0, help="read requests per second (default 50)")
    p.add_argument("--read-seconds", type=float, default=20.0, help="length of each read window (default 20 s)")
    p.add_argument("--timeout-s", type=float, default=900.0, help="longest run of the clinicians (default 900 s)")
    p.add_argument("--same-files", action="store_true",
                   help="every clinician uploads the reference session's files (stored once) instead of their own")
    return p


def main(argv: list[str] | None = None) -> Summary:
    """Run the benchmark, print its tables and return the :class:`Summary` (``exit_status`` for a check)."""
    args = _parser().parse_args(argv)
    if args.clinicians < 1 or args.workers < 1 or args.read_rate <= 0 or args.read_seconds <= 0:
        raise SystemExit("--clinicians, --workers, --read-rate and --read-seconds must be positive")
    with tempfile.TemporaryDirectory(prefix="chakamo-load-") as tmp:
        files = sessions(Path(tmp), args.clinicians, args.same_files)
        with running_stack(Path(tmp), args.backend, args.workers) as stack:
            summary = run(stack, files, args)
            print_tables(summary, stack, args)
            if summary.exit_status:
                print("\nWhat the processes logged last (the logs go with the temporary folder):\n")
                print(failure_excerpt(stack))
    return summary


if __name__ == "__main__":
    try:
        raise SystemExit(main().exit_status)
    except Missing as exc:
        raise SystemExit(f"cannot run the load benchmark: {exc}") from None
