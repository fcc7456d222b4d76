"""Processing jobs: persisted in the database, run off the request path, resumed after a restart.

Interface (ready for a distributed engine): a :class:`JobRunner` has ``start()``, ``submit(job_id)`` and
``shutdown()``.  The API only inserts a ``jobs`` row (status ``queued``) in the same transaction that
checks the session, then calls ``submit``; the runner does the rest.  :func:`run_job` is the unit of
work any engine calls with a job id — a Celery task would call it too.

:class:`ThreadJobRunner`, the embedded default, is N worker threads fed by a queue of job ids.  A worker
*claims* a job with a conditional UPDATE (``queued`` → ``running``), so two runners sharing one database
never run the same job twice.  On ``start()`` jobs found ``running`` (their process died mid-way) go back
to ``queued`` with a log line, and every queued job is submitted again, oldest first: nothing is lost by a
restart; a resumed job starts over from its stored files (processing is deterministic); one interrupted
:data:`MAX_ATTEMPTS` times is failed instead (it may be what brings the server down).  The embedded
runner assumes one server process per database (``chakamo serve``): a second process starting up would
requeue the first one's running jobs.  Several processes or machines need the distributed backend
(``CHAKAMO_JOB_BACKEND``, next issue), which calls :func:`run_job` from its workers.

A job's work (:func:`run_job`): copy the session's stored files into a temporary folder with its
``session.json`` (:mod:`app.workspace`), load and process them (:func:`app.pipeline.process_session`, its
``progress(stage, fraction)`` calls written to the job row), build ``results.json`` once and render every
artefact from one report input — ``report.pdf`` in es, en and pt, ``angles.xlsx``, ``quaternions.xlsx``,
``report.html``, ``scene.viser`` (in the job's language) and ``timeseries.npz`` — the two other PDFs and
angles.xlsx in a warm helper process when one is configured (:class:`RenderPool`) — store them as blobs and
record a new :class:`~app.db.models.Analysis` in one transaction.  Earlier analyses stay.  A problem with the
data (ingestion or pipeline error) fails the job with the pipeline's sentence as ``error``; an unexpected
exception fails it with its type and message and the traceback in the log.
"""

from __future__ import annotations

import dataclasses
import io
import logging
import os
import queue
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import Protocol

from sqlalchemy import select, update

from app.db import Database
from app.db.models import Analysis, Artefact, Blob, Job, KneeSession, Patient, Recording, utcnow
from app.storage import BlobStore

log = logging.getLogger("chakamo.jobs")

LANGS = ("es", "en", "pt")
MEDIA = {
    "results.json": "application/json",
    "report.pdf": "application/pdf",
    "angles.xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
    "quaternions.xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
    "report.html": "text/html; charset=utf-8",
    "scene.viser": "application/octet-stream",
    "timeseries.npz": "application/octet-stream",
}
#: a job interrupted by this many server stops is failed instead of resumed again
MAX_ATTEMPTS = 3
#: share of the progress bar taken by the pipeline; the rest is the reports
_PIPELINE_SHARE = 0.6


class JobRunner(Protocol):
    """What the application needs of a job engine."""

    def start(self) -> None: ...

    def submit(self, job_id: int) -> None: ...

    def shutdown(self, wait: bool = True) -> None: ...


class _Progress:
    """Writes ``stage`` / ``progress`` and a log line to the job row (one short transaction each)."""

    def __init__(self, db: Database, job_id: int) -> None:
        self.db, self.job_id = db, job_id

    def __call__(self, stage: str, fraction: float, *, note: str | None = None) -> None:
        with self.db.session() as s:
            job = s.get(Job, self.job_id)
            job.stage, job.progress = stage[:40], float(min(max(fraction, 0.0), 1.0))
            job.log = [*job.log, f"{utcnow().isoformat(timespec='seconds')} {note or stage}"]


def _fail(db: Database, job_id: int, error: str, detail: str | None = None) -> None:
    with db.session() as s:
        job = s.get(Job, job_id)
        job.status, job.error, job.finished_at = "failed", error, utcnow()
        job.log = [*job.log, f"{utcnow().isoformat(timespec='seconds')} failed: {error}",
                   *([detail] if detail else [])]


def claim(db: Database, job_id: int) -> bool:
    """Mark job ``job_id`` running if it is queued; False when another worker has it (or it is finished)."""
    with db.session() as s:
        res = s.execute(update(Job).where(Job.id == job_id, Job.status == "queued")
                        .values(status="running", started_at=utcnow(), attempts=Job.attempts + 1,
                                stage="start", progress=0.0, error=None))
        return res.rowcount == 1


def _public_results(results: dict, session_id: int) -> dict:
    """results.json without the server's temporary folder in it."""
    sess = results.get("session", {})
    sess["folder"] = f"session {session_id}"
    for src in sess.get("recognised", {}).values():
        if isinstance(src, dict) and "files" in src:
            src["files"] = [Path(f).name for f in src["files"]]
    return results


def render_artefact(ri, name: str, lang: str = "") -> bytes:
    """One artefact of report input ``ri`` as bytes (top-level: runs in the render process too)."""
    if name == "report.pdf":
        from reports.pdf import render_pdf

        return render_pdf(dataclasses.replace(ri, language=lang))
    if name in ("angles.xlsx", "quaternions.xlsx"):
        from reports.excel import write_angles_xlsx, write_quaternions_xlsx

        writer = write_angles_xlsx if name == "angles.xlsx" else write_quaternions_xlsx
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / name
            writer(ri, path)
            return path.read_bytes()
    if name == "report.html":
        from reports.html import render_html

        return render_html(ri).encode("utf-8")
    if name == "scene.viser":
        from reports.scene import scene_bytes

        return scene_bytes(ri)
    raise ValueError(f"unknown artefact {name!r}")


def render_many(ri, keys: list[tuple[str, str]]) -> dict[tuple[str, str], bytes]:
    """:func:`render_artefact` for each ``(name, lang)`` of ``keys``."""
    return {key: render_artefact(ri, *key) for key in keys}


def _render(outcome, results: dict, lang: str, progress: _Progress, pool: "RenderPool | None" = None
            ) -> dict[tuple[str, str], bytes]:
    """Every artefact from one report input: ``{(name, lang): bytes}`` (lang "" unless a PDF).

    With a warm :class:`RenderPool`, the two other-language PDFs and angles.xlsx are rendered in the
    render process while this thread renders the rest (the report code holds the GIL: threads would not
    overlap); without one, or if that process fails, everything is rendered here.
    """
    from app.results import report_input, results_json, timeseries_npz

    ri = report_input(outcome, results)
    files: dict[tuple[str, str], bytes] = {("results.json", ""): results_json(results).encode("utf-8"),
                                           ("timeseries.npz", ""): timeseries_npz(outcome)}
    others = [("report.pdf", x) for x in LANGS if x != lang]
    # about equal halves (measured: a PDF 0.2-0.4 s, angles.xlsx 0.1 s, quaternions.xlsx 0.2 s, html 0.05 s,
    # scene 0.2 s)
    local = [("report.pdf", lang), ("report.html", ""), ("scene.viser", ""), ("quaternions.xlsx", "")]
    remote = [*others, ("angles.xlsx", "")]
    future = pool.submit(render_many, ri, remote) if pool is not None else None
    if future is None:
        local, remote = local + remote, []
    for i, (name, x) in enumerate(local):
        progress(f"{name} {x}".strip(), _PIPELINE_SHARE + (1 - _PIPELINE_SHARE) * i / (len(local) + 1))
        files[(name, x)] = render_artefact(ri, name, x)
    if future is not None:
        progress("reports (render process)", 0.95)
        try:
            files |= future.result()
        except Exception:  # noqa: BLE001 — e.g. the render process died: render here instead
            log.exception("render process failed; rendering in the job thread")
            files |= render_many(ri, remote)
    return files


def _exit_with_parent(parent_pid: int) -> None:
    """In a render process: exit as soon as the server process is gone (even killed with SIGKILL)."""
    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(1.0)
        os._exit(0)

    threading.Thread(target=watch, name="chakamo-parent-watch", daemon=True).start()


class RenderPool:
    """One warm helper process for report rendering (``CHAKAMO_RENDER_PROCESSES``; 0 = none).

    Started with ``spawn`` (forking a threaded server is unsafe), exits when the server process does (even
    one killed with SIGKILL), and is warmed up by importing the report modules; :meth:`submit` returns None until it is warm, so a job never waits for its start-up.
    """

    def __init__(self, processes: int) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self._pool = ProcessPoolExecutor(processes, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_exit_with_parent, initargs=(os.getpid(),))
        self._warm = self._pool.submit(warm_up)

    def submit(self, fn, *args):
        if not self._warm.done() or self._warm.exception() is not None:
            return None
        try:
            return self._pool.submit(fn, *args)
        except Exception:  # noqa: BLE001 — a broken pool: the caller renders itself
            log.exception("render pool unavailable")
            return None

    def wait_warm(self, timeout_s: float = 120.0) -> bool:
        """Block until the process is warm (benchmarks, tests); True if it is usable."""
        try:
            self._warm.result(timeout_s)
            return True
        except Exception:  # noqa: BLE001
            return False

    def shutdown(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)


def run_job(job_id: int, db: Database, store: BlobStore, tmp_root: Path, pool: RenderPool | None = None) -> None:
    """Claim and run job ``job_id`` to ``done`` or ``failed`` (module docstring).  Never raises for bad data."""
    from app.ingestion import IngestionError, load_session
    from app.pipeline import PipelineError, ProcessOptions, process_session
    from app.results import build_results
    from app.workspace import materialise, public_message

    if not claim(db, job_id):
        return
    progress = _Progress(db, job_id)
    folder = None
    try:
        with db.session() as s:
            job = s.get(Job, job_id)
            session = s.get(KneeSession, job.session_id)
            patient = s.get(Patient, session.patient_id)
            recordings = list(s.scalars(select(Recording).where(Recording.session_id == session.id)
                                        .order_by(Recording.id)))
            s.expunge_all()
        progress("read", 0.01, note=f"started (attempt {job.attempts}): filter {job.filter}, language {job.lang}")
        options = ProcessOptions(filter_name=job.filter, language=job.lang)
        with materialise(store, tmp_root, session, patient, recordings) as folder:
            loaded = load_session(folder)
            outcome = process_session(loaded, options,
                                      progress=lambda st, f: progress(st, 0.02 + (_PIPELINE_SHARE - 0.02) * f))
        results = _public_results(build_results(outcome), session.id)
        files = _render(outcome, results, job.lang, progress, pool)
        progress("store", 0.99)
        stored = {key: store.put(data) for key, data in files.items()}
        with db.session() as s:
            for sha, size in set(stored.values()):
                if s.get(Blob, sha) is None:
                    s.add(Blob(sha256=sha, size_bytes=size))
            analysis = Analysis(session_id=session.id, job_id=job_id, filter=job.filter, lang=job.lang,
                                accepted_cycles=int(results["cycles"]["accepted"]),
                                warnings=len(results["quality"]["warnings"]))
            analysis.artefacts = [Artefact(name=name, lang=lang, media_type=MEDIA[name], sha256=sha, size_bytes=size)
                                  for (name, lang), (sha, size) in stored.items()]
            s.add(analysis)
            s.flush()
            row = s.get(Job, job_id)
            row.status, row.stage, row.progress, row.finished_at = "done", "done", 1.0, utcnow()
            row.analysis_id = analysis.id
            row.log = [*row.log, f"{utcnow().isoformat(timespec='seconds')} done: analysis {analysis.id}, "
                                 f"{analysis.accepted_cycles} cycles accepted, {analysis.warnings} warnings"]
    except (IngestionError, PipelineError) as exc:
        _fail(db, job_id, public_message(str(exc), folder))
    except Exception as exc:  # noqa: BLE001 — a job must end failed, never stay running
        log.exception("job %s failed", job_id)
        buf = io.StringIO()
        traceback.print_exc(file=buf)
        _fail(db, job_id, f"internal error ({type(exc).__name__}: {exc}); the log has the details — report it "
                          "to the ChakaMo maintainers", buf.getvalue()[-4000:])


def warm_up() -> None:
    """Before the first job needs them: import the processing and report modules (≈1 s), make the PDF's font
    cut (once per machine, ≈0.3 s) and run the default orientation filter once on one second of still data
    (loads its compiled numba kernels, ≈0.3 s)."""
    import importlib

    for name in ("app.pipeline", "app.results", "reports.excel", "reports.html", "reports.pdf", "reports.scene"):
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 — the job importing it will report the problem
            log.exception("warm-up import of %s failed", name)
    try:
        from reports.fonts import font_files

        font_files()
    except Exception:  # noqa: BLE001 — only a warm-up
        log.exception("warm-up of the PDF font failed")
    try:
        import numpy as np

        from estimators.orientation import DEFAULT_METHOD, make

        n = 100
        acc = np.tile([0.0, 0.0, 9.81], (n, 1))
        mag = np.tile([0.0, 20.0, -40.0], (n, 1))
        make(DEFAULT_METHOD).estimate(acc, np.zeros((n, 3)), mag, fs_hz=100.0)
    except Exception:  # noqa: BLE001 — only a warm-up
        log.exception("warm-up run of the orientation filter failed")


class ThreadJobRunner:
    """The embedded engine: ``workers`` threads taking job ids from a queue (module docstring)."""

    def __init__(self, db: Database, store: BlobStore, tmp_root: Path, workers: int = 2,
                 render_processes: int = 0) -> None:
        self.db, self.store, self.tmp_root, self.workers = db, store, Path(tmp_root), workers
        self.render_processes = render_processes
        self.pool: RenderPool | None = None
        self._queue: queue.Queue[int | None] = queue.Queue()
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()

    def start(self) -> None:
        """Requeue jobs left ``running``, start the threads and submit every queued job, oldest first."""
        self._stop.clear()
        if self.render_processes > 0 and self.pool is None:
            self.pool = RenderPool(self.render_processes)
        with self.db.session() as s:
            for job in s.scalars(select(Job).where(Job.status == "running")):
                stamp = utcnow().isoformat(timespec="seconds")
                if job.attempts >= MAX_ATTEMPTS:  # it keeps taking the server down with it: stop trying
                    job.status, job.finished_at = "failed", utcnow()
                    job.error = (f"processing was interrupted {job.attempts} times (the server stopped each time); "
                                 "check the server's memory and logs, then process the session again")
                    job.log = [*job.log, f"{stamp} interrupted again; given up"]
                    continue
                job.status, job.stage = "queued", "queued"
                job.log = [*job.log, f"{stamp} interrupted (server stopped); queued again"]
            pending = list(s.scalars(select(Job.id).where(Job.status == "queued").order_by(Job.id)))
        for i in range(self.workers):
            t = threading.Thread(target=self._work, name=f"chakamo-job-{i}", daemon=True)
            t.start()
            self._threads.append(t)
        for job_id in pending:
            self.submit(job_id)
        threading.Thread(target=warm_up, name="chakamo-warm-up", daemon=True).start()

    def submit(self, job_id: int) -> None:
        self._queue.put(job_id)

    def _work(self) -> None:
        while True:
            job_id = self._queue.get()
            if job_id is None or self._stop.is_set():  # a queued job left here stays queued in the database
                return
            try:
                run_job(job_id, self.db, self.store, self.tmp_root, self.pool)
            except Exception:  # noqa: BLE001 — e.g. the database went away: keep the worker alive
                log.exception("worker could not run job %s", job_id)

    def shutdown(self, wait: bool = True, timeout_s: float = 60.0) -> None:
        """Stop the threads after their current job; queued jobs stay queued for the next start (a job cut
        short by the process' exit is resumed then too)."""
        self._stop.set()
        for _ in self._threads:
            self._queue.put(None)
        if wait:
            for t in self._threads:
                t.join(timeout_s)
        self._threads.clear()
        if self.pool is not None:
            self.pool.shutdown()
            self.pool = None


__all__ = ["JobRunner", "MEDIA", "RenderPool", "ThreadJobRunner", "claim", "render_artefact", "render_many", "run_job",
           "warm_up"]
