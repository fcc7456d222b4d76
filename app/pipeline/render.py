"""Artefact rendering: every output file of an analysis from one report input, and the server's warm helper processes.

:func:`render_all` builds ``results.json`` and ``timeseries.npz`` and renders ``report.pdf`` and ``report.html`` in
every language of :data:`reports.i18n.LANGUAGES`, ``angles.xlsx``, ``quaternions.xlsx`` and ``scene.viser``
(:func:`render_artefact` is one of them), one after another in the calling process — a job's helper process
(:mod:`app.jobs.compute`) or a Celery worker.  :func:`warm_up` imports the report modules and runs the default
filter once, so a job never pays for that.  :class:`RenderPool` is a warm spawned helper process at background
priority: the upload checks' helpers (:class:`app.store.checks.CheckPool`) and, as their base class, the embedded
engine's job helpers (:class:`app.jobs.compute.JobProcess`, which render too).  The job's computation
(:func:`app.jobs.compute.compute`) calls :func:`render_all`; nothing here touches the database.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import signal
import tempfile
import threading
import time
from concurrent.futures import TimeoutError as FutureTimeout
from pathlib import Path

from reports.i18n import LANGUAGES

log = logging.getLogger("chakamo.render")

#: the languages of the PDF report (one definition: :data:`reports.i18n.LANGUAGES`)
LANGS = LANGUAGES
MEDIA = {
    "results.json": "application/json",
    "report.pdf": "application/pdf",
    "angles.xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
    "quaternions.xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
    "report.html": "text/html; charset=utf-8",
    "scene.viser": "application/octet-stream",
    "timeseries.npz": "application/octet-stream",
    "patient.json": "application/json",
}
#: share of the progress bar taken by the pipeline; the rest is the reports
PIPELINE_SHARE = 0.6
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

        return render_html(dataclasses.replace(ri, language=lang) if lang else ri).encode("utf-8")
    if name == "scene.viser":
        from reports.scene import scene_bytes

        return scene_bytes(ri)
    if name == "timeseries.npz":  # also from the outcome: app.pipeline.results.timeseries_npz
        from app.pipeline.results import timeseries_npz_of

        return timeseries_npz_of(ri)
    raise ValueError(f"unknown artefact {name!r}")


def patient_json(patient) -> bytes:
    """``patient.json``: the identity block the job's reports printed (:class:`reports.model.Patient`, every field),
    kept with the analysis so its reports can be rendered again later (a signed interpretation) with the identity
    the job used, never the patient's data as corrected since (:mod:`app.store.signed_reports`)."""
    import json

    return json.dumps(dataclasses.asdict(patient), ensure_ascii=False, sort_keys=True).encode("utf-8")


def render_all(outcome, results: dict, lang: str, progress, knees=None) -> dict[tuple[str, str], bytes]:
    """Every artefact from one report input: ``{(name, lang): bytes}`` (lang "" unless a PDF or the HTML report),
    the reports in ``lang`` first.  ``progress(stage, fraction)`` is told each step.  ``knees``: the
    :class:`app.pipeline.knees.KneesOutcome` of a session of both knees (``outcome`` its top-level knee).
    """
    from app.pipeline.results import report_input, results_json, timeseries_npz

    ri = report_input(outcome, results, knees=knees)
    files: dict[tuple[str, str], bytes] = {("results.json", ""): results_json(results).encode("utf-8"),
                                           ("timeseries.npz", ""): timeseries_npz(outcome, knees),
                                           ("patient.json", ""): patient_json(ri.patient)}
    keys = [("report.pdf", lang), ("report.html", lang), ("scene.viser", ""), ("quaternions.xlsx", ""),
            ("angles.xlsx", ""), *[(name, x) for x in LANGS if x != lang for name in ("report.pdf", "report.html")]]
    for i, (name, x) in enumerate(keys):
        progress(f"{name} {x}".strip(), PIPELINE_SHARE + (1 - PIPELINE_SHARE) * i / (len(keys) + 1))
        files[(name, x)] = render_artefact(ri, name, x)
    return files


#: ``chakamo process``'s rendered artefacts as two groups of about equal cost, one per forked render process:
#: the PDF is the one large piece, the rest balance it.  CPU on the 10-cycle demo session, each in a helper
#: after :func:`warm_up` (``processing=False``) and :func:`preload_renderers`: PDF 0.14 s, timeseries.npz 0.02 (its compression) | angles.xlsx
#: 0.04, HTML 0.025, scene 0.03, quaternions.xlsx 0.065 — 0.16 s each (the old split, PDF + angles.xlsx + HTML |
#: scene + quaternions.xlsx + npz, was 0.22 | 0.14 s); ``python -m benchmarks.cold`` prints them
FORK_GROUPS: tuple[tuple[str, ...], ...] = (("report.pdf", "timeseries.npz"),
                                             ("angles.xlsx", "report.html", "scene.viser", "quaternions.xlsx"))


def render_named(ri, names) -> dict[str, bytes]:
    """``{name: bytes}`` of :func:`render_artefact` for ``names``, the PDF in the report input's language; each
    one timed as its own stage (``CHAKAMO_TIMINGS``)."""
    from app.pipeline import timings

    out = {}
    for name in names:
        with timings.stage(name):
            out[name] = render_artefact(ri, name, ri.language if name == "report.pdf" else "")
    return out


#: what the renderers import only when they first run: plotly for the HTML, viser and its message classes for
#: the scene, and rich, which viser's server imports as it starts (for its banner, silenced)
RENDER_TIME_IMPORTS = ("plotly.offline", "viser", "viser._messages", "rich.console", "rich.table")


def preload_renderers() -> None:
    """Load what :func:`render_artefact` loads on its first call whatever the session: :data:`RENDER_TIME_IMPORTS`,
    the translation tables and plotly.js (≈0.03 s of CPU, ≈0.04 s less in the first reports: the scene 0.02,
    the HTML 0.01, the PDF 0.01).  For :class:`ForkedRenderers`' helpers, which have this time while the parent
    computes; the bytes rendered are the same."""
    import importlib

    from reports.html import plotly_js
    from reports.i18n import table

    for name in RENDER_TIME_IMPORTS:
        importlib.import_module(name)
    table()
    plotly_js()


def _write_all(fd: int, data: bytes) -> None:
    """One length-prefixed message on ``fd``, then closed."""
    with os.fdopen(fd, "wb") as f:
        f.write(len(data).to_bytes(8, "little"))
        f.write(data)


def _read_all(fd: int) -> bytes | None:
    """A length-prefixed message from ``fd`` (then closed), None when the writer closed it without one."""
    with os.fdopen(fd, "rb") as f:
        head = f.read(8)
        if len(head) < 8:
            return None
        size = int.from_bytes(head, "little")
        data = f.read(size)
    return data if len(data) == size else None


class ForkedRenderers:
    """Helper processes forked at the start of a one-shot command (``chakamo process``), for a cold start.

    A fresh ``chakamo process`` spends most of its time importing libraries and loading numba's cached
    kernels, on one core; the report libraries (fpdf2, openpyxl, viser, plotly) cost ~0.5 s more of imports
    that do not depend on the session, and reading the files ~0.15 s that needs no numba.  So, before numpy
    is even imported, the command forks one helper.  Given ``read=(session folder, expected rate)`` it first
    reads the session (:func:`app.pipeline.ingestion.load_knees`: every knee; :meth:`session` hands them over,
    pickled) while the parent loads numba; then it imports the report modules (and makes the PDF's font cut), loads
    what they load on a first call (:func:`preload_renderers`), and forks once per further group of
    :data:`FORK_GROUPS`.  When the parent has the report input
    (:meth:`render`, pickled through one pipe per helper), the helpers render their groups side by side and
    send the bytes back; the parent writes every file itself (all or nothing,
    :func:`app.pipeline.results.write_outputs`).  The bytes are those of :func:`render_artefact` in the parent
    (``tests/app/pipeline/test_forked_render.py``; ``python -m benchmarks.same_outputs``).  A helper that
    fails or dies is not fatal: what it did not deliver is rendered (or read) in the parent.

    Only for a process with a single thread and no event loop (fork copies none of them, nor the locks they
    hold): the CLI creates it first thing; a server renders in its spawned job helpers
    (:class:`app.jobs.compute.JobProcess`, a :class:`RenderPool`) or its Celery workers.  Use as a context
    manager, or call :meth:`close`.  Without ``os.fork`` (Windows), or with other threads running, nothing is
    forked: :meth:`render` renders in the caller and :meth:`session` is None.
    """

    def __init__(self, groups: tuple[tuple[str, ...], ...] = FORK_GROUPS, *,
                 read: tuple[str | os.PathLike, float | None] | None = None) -> None:
        self.groups = groups
        self.pid: int | None = None
        self._session_reader: threading.Thread | None = None
        self._tasks: list[int] = []
        self._results: list[int] = []
        if not hasattr(os, "fork") or threading.active_count() > 1:  # Windows; or threads fork would not copy
            return
        tasks = [os.pipe() for _ in groups]  # parent -> helper g: the report input
        results = [os.pipe() for _ in groups]  # helper g -> parent: its artefacts
        session_r, session_w = os.pipe() if read is not None else (None, None)
        pid = os.fork()
        if pid == 0:  # the helper: never returns into the caller's code
            code = 0
            try:
                for fd in [w for _, w in tasks] + [r for r, _ in results] + ([session_r] if read else []):
                    os.close(fd)
                self._helper([r for r, _ in tasks], [w for _, w in results], read, session_w)
            except BaseException:  # noqa: BLE001 — the parent renders what it does not receive
                code = 1
            finally:
                os._exit(code)
        for fd in [r for r, _ in tasks] + [w for _, w in results] + ([session_w] if read else []):
            os.close(fd)
        self.pid, self._tasks, self._results = pid, [w for _, w in tasks], [r for r, _ in results]
        self._session_message: list[bytes | None] = [None]
        if session_r is not None:  # drained by a thread: the helper goes on to its imports at once
            self._session_reader = threading.Thread(target=self._drain_session, args=(session_r,),
                                                    name="chakamo-session-reader", daemon=True)
            self._session_reader.start()

    # ----------------------------------------------------------------------------------- the helpers' side
    def _helper(self, task_rs: list[int], result_ws: list[int], read, session_w: int | None) -> None:
        import pickle

        from app.pipeline import timings

        if read is not None:  # the session first: the parent needs it soonest
            try:
                with timings.stage("read"):
                    from app.pipeline.ingestion import load_knees

                    session = load_knees(read[0], expected_fs_hz=read[1])
                payload = pickle.dumps(session, protocol=pickle.HIGHEST_PROTOCOL)
            except BaseException:  # noqa: BLE001 — the parent reads it again and reports the error itself
                payload = b""
            _write_all(session_w, payload)
        with timings.stage("render.imports"):
            warm_up(processing=False)
            preload_renderers()  # before the forks below: every render helper has them
        children = []
        for g in range(1, len(self.groups)):  # forked now, before the report input arrives
            pid = os.fork()
            if pid == 0:
                code = 0
                try:
                    for fd in task_rs[:g] + task_rs[g + 1:] + result_ws[:g] + result_ws[g + 1:]:
                        os.close(fd)
                    self._render_group(g, task_rs[g], result_ws[g])
                except BaseException:  # noqa: BLE001
                    code = 1
                finally:
                    os._exit(code)
            children.append(pid)
        for fd in task_rs[1:] + result_ws[1:]:
            os.close(fd)
        try:
            self._render_group(0, task_rs[0], result_ws[0])
        finally:
            for pid in children:
                os.waitpid(pid, 0)

    def _render_group(self, g: int, task_r: int, result_w: int) -> None:
        """Helper ``g``: wait for the report input, render its group, send ``("ok", {name: bytes})`` (or the
        traceback); nothing when the parent ended without sending one (an error: nothing to render)."""
        import pickle
        import resource
        import traceback

        from app.pipeline import timings

        task = _read_all(task_r)
        if task is None:
            os.close(result_w)
            return
        cpu0 = time.process_time()
        try:
            out = render_named(pickle.loads(task), self.groups[g])
            payload = pickle.dumps(("ok", out), protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException:  # noqa: BLE001 — reported to the parent, which renders the group itself
            payload = pickle.dumps(("error", traceback.format_exc()))
        timings.report_process(f"render{g + 1}", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                               time.process_time() - cpu0)
        _write_all(result_w, payload)

    # ----------------------------------------------------------------------------------- the parent's side
    @property
    def reading(self) -> bool:
        """True while the helper's session (``read=``) has not been collected by :meth:`session`."""
        return self._session_reader is not None

    @property
    def read_failed(self) -> bool:
        """True when the helper has already answered that it could not read the session (a missing folder,
        files it refused): the caller then reads it at once and reports the error without loading numba."""
        reader = self._session_reader
        return reader is not None and not reader.is_alive() and not self._session_message[0]

    def _drain_session(self, fd: int) -> None:
        self._session_message[0] = _read_all(fd)

    def session(self):
        """The session the helper read (``read=(folder, expected_fs_hz)``), or None when it was not asked to
        or could not (an error: the caller reads it again and so reports the error itself)."""
        reader, self._session_reader = self._session_reader, None
        if reader is None:
            return None
        reader.join()
        message, self._session_message[0] = self._session_message[0], None
        if not message:
            return None
        import pickle

        return pickle.loads(message)

    def render(self, ri) -> dict[str, bytes]:
        """Every artefact of the groups for report input ``ri``: ``{name: bytes}`` (:func:`render_named`)."""
        names = [name for group in self.groups for name in group]
        if self.pid is None:
            return render_named(ri, names)
        import pickle

        task = pickle.dumps(ri, protocol=pickle.HIGHEST_PROTOCOL)
        tasks, self._tasks = self._tasks, []
        for fd in tasks:
            try:
                _write_all(fd, task)
            except OSError:  # that helper is gone: its group is rendered here
                log.exception("a render helper did not take the report input; rendering its part here")
        out: dict[str, bytes] = {}
        results, self._results = self._results, []
        for g, fd in enumerate(results):
            message = _read_all(fd)
            status, payload = pickle.loads(message) if message is not None else ("error", "no answer")
            if status == "ok":
                out |= payload
            else:
                log.error("render helper %d failed (%s); rendering its artefacts here", g + 1, payload)
        self._reap()
        return out | render_named(ri, [name for name in names if name not in out])

    def close(self) -> None:
        """End unused helpers (the command failed before its reports) at once and reap them: a user's error
        message must not wait for the report libraries' imports.  (Killed while it makes the PDF's font cut,
        once per machine, the helper can leave a temporary file in the font cache; the next run cuts again.)"""
        if self.pid is None:
            return
        if self._tasks:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGKILL)  # its forked render helpers see their pipes end and exit
        for fd in self._tasks + self._results:
            os.close(fd)
        self._tasks, self._results = [], []
        self._reap()
        if self._session_reader is not None:  # the helper is gone: its pipe has ended
            self._session_reader.join()
            self._session_reader = None

    def _reap(self) -> None:
        if self.pid is not None:
            os.waitpid(self.pid, 0)
            self.pid = None

    def __enter__(self) -> "ForkedRenderers":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: nice increment of the server's helper processes (:class:`RenderPool`: upload checks and jobs): under CPU starvation
#: the scheduler serves the API process first (issue 16 finding 10h); 10 gives a busy nice-0 process about nine
#: times the CPU of a busy helper (the kernel's weights 1024 : 110).  Only processes: a lowered thread of the API
#: process would hold the interpreter's and the database's locks at that priority (:mod:`app.jobs.inprocess`)
BACKGROUND_NICE = 10


def lower_priority() -> bool:
    """Lower this process' CPU priority by :data:`BACKGROUND_NICE` (a helper process at start-up); the
    processes it starts inherit it.  Returns whether it was lowered."""
    try:
        os.nice(BACKGROUND_NICE)
    except (AttributeError, OSError):  # no os.nice (Windows), or not permitted: run at the usual priority
        return False
    return True


def exit_with_parent(parent_pid: int) -> None:
    """In a server's helper process (an upload check's or a job's): run at the background priority (:data:`BACKGROUND_NICE`), and exit as
    soon as the server process is gone (even killed with SIGKILL)."""
    lower_priority()
    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(1.0)
        os._exit(0)

    threading.Thread(target=watch, name="chakamo-parent-watch", daemon=True).start()


class RenderPool:
    """A warm helper process (or ``processes`` of them) at background priority: the upload checks' helpers
    (:class:`app.store.checks.CheckPool`), and the base of the embedded engine's job helpers
    (:class:`app.jobs.compute.JobProcess`, which submits to its pool itself).

    Started with ``spawn`` (forking a threaded server is unsafe), exits when the server process does (even
    one killed with SIGKILL), and is warmed up by ``warm`` (default :func:`warm_up`: the report modules);
    :meth:`submit` waits for its start-up no longer than its caller says, and answers None past that: the
    caller refuses the work, it does not do it itself (an upload check done in the API process is what a
    crafted file needs to stall it: issue 16, finding 4).  :meth:`restart`
    replaces a hung or dead process — only then: work that raised leaves the process as it is (the upload
    checks' helpers are pools of one, :class:`app.store.checks.CheckPool`).
    """

    def __init__(self, processes: int, warm=None) -> None:
        self.processes = processes
        self._warm_fn = warm or warm_up
        self._lock = threading.Lock()  # restart() (a request's or a job's thread) against shutdown() (the server's)
        self._stopping = False
        self._start()

    def _start(self) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        ctx = multiprocessing.get_context("spawn")
        initializer, initargs = self._initializer(ctx)
        self._pool = ProcessPoolExecutor(self.processes, mp_context=ctx, initializer=initializer, initargs=initargs)
        self._warm = self._pool.submit(self._warm_fn)  # starts the process now, not at the first task

    def _initializer(self, ctx):
        """``(initializer, initargs)`` of the processes (made with the ``spawn`` context ``ctx``): background
        priority and exit with the server (:func:`exit_with_parent`); a subclass may add to it."""
        return exit_with_parent, (os.getpid(),)

    def _stop(self) -> None:
        """Terminate the processes (their work too) and drop the pool."""
        for proc in list((getattr(self._pool, "_processes", None) or {}).values()):  # no public way to stop one
            proc.terminate()
        self._pool.shutdown(wait=False, cancel_futures=True)

    def restart(self) -> None:
        """Replace a hung or dead process by a fresh one (its work is abandoned); after :meth:`shutdown`,
        nothing."""
        with self._lock:
            if self._stopping:
                return
            self._stop()
            self._start()

    @property
    def stopping(self) -> bool:
        """True once :meth:`shutdown` began: the helper's work was stopped by the server, not by a fault."""
        return self._stopping

    def submit(self, fn, *args, wait_s: float = 0.0):
        """``fn(*args)`` in the helper process (a future), once it is warm: its start-up (the first, or after a
        :meth:`restart`, e.g. a check's time-out) is waited for up to ``wait_s``.  A process found dead (it
        ended while idle: killed, out of memory; or its warm-up failed) is replaced and the new one waited for
        within the same ``wait_s``, once.  None when no process was usable within ``wait_s``, and after
        :meth:`shutdown` (quietly: a server stopping is not a fault to log)."""
        deadline = time.monotonic() + wait_s
        replaced = False
        while not self._stopping:
            try:
                self._warm.result(max(0.0, deadline - time.monotonic()))
            except FutureTimeout:  # still starting
                return None
            except Exception:  # noqa: BLE001 — the warm-up failed or was cancelled: a dead process
                why = "its warm-up failed"
                if not self._stopping:  # a shutdown cancels it: quiet
                    log.warning("the helper process' warm-up failed", exc_info=True)
            else:
                why = "it had ended while idle"
                if self._alive():
                    try:
                        return self._pool.submit(fn, *args)
                    except Exception:  # noqa: BLE001 — broken meanwhile (or shut down: the loop ends)
                        why = "its pool was unusable"
                        if not self._stopping:
                            log.warning("helper process pool unavailable", exc_info=True)
            if replaced or self._stopping:
                return None
            log.warning("replacing the helper process (%s)", why)
            self.restart()
            replaced = True
        return None

    def _alive(self) -> bool:
        """False when the helper is known dead (its pool broken, or its process exited)."""
        procs = getattr(self._pool, "_processes", None) or {}
        return not getattr(self._pool, "_broken", False) and all(p.exitcode is None for p in list(procs.values()))

    def wait_warm(self, timeout_s: float = 120.0) -> bool:
        """Block until the process is warm (benchmarks, tests); True if it is usable."""
        try:
            self._warm.result(timeout_s)
            return True
        except Exception:  # noqa: BLE001
            return False

    def shutdown(self) -> None:
        """Stop the processes now, their work too: the interpreter's exit would otherwise wait for a running task
        (a server stopping during an upload check, or a job).  The caller waiting for that task gets
        :class:`~concurrent.futures.process.BrokenProcessPool`; :meth:`restart` does nothing afterwards."""
        with self._lock:
            if self._stopping:
                return
            self._stopping = True
            self._stop()


def warm_up(processing: bool = True) -> None:
    """Before the first job needs them: import the processing and report modules (≈1 s), make the PDF's font
    cut (once per machine, ≈0.3 s) and run the default orientation filter once on one second of still data
    (loads its compiled numba kernels, ≈0.3 s).  ``processing=False``: the report side only (no numba)."""
    import importlib

    names = ("app.pipeline.session", "app.pipeline.results") if processing else ()
    for name in names + ("reports.excel", "reports.html", "reports.pdf", "reports.scene"):
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 — the job importing it will report the problem
            log.exception("warm-up import of %s failed", name)
    try:
        from reports.fonts import font_files

        font_files()
    except Exception:  # noqa: BLE001 — only a warm-up
        log.exception("warm-up of the PDF font failed")
    if not processing:
        return
    try:
        import numpy as np

        from estimators.orientation import DEFAULT_METHOD, make

        n = 100
        acc = np.tile([0.0, 0.0, 9.81], (n, 1))
        mag = np.tile([0.0, 20.0, -40.0], (n, 1))
        make(DEFAULT_METHOD).estimate(acc, np.zeros((n, 3)), mag, fs_hz=100.0)
    except Exception:  # noqa: BLE001 — only a warm-up
        log.exception("warm-up run of the orientation filter failed")


__all__ = ["BACKGROUND_NICE", "FORK_GROUPS", "LANGS", "MEDIA", "PIPELINE_SHARE", "patient_json", "RENDER_TIME_IMPORTS",
           "ForkedRenderers", "RenderPool", "exit_with_parent", "lower_priority", "preload_renderers", "render_all", "render_artefact",
           "render_named", "warm_up"]
