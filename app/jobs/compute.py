"""A job's computation — read the files, process the knees, build ``results.json``, render every artefact — and the
helper process the embedded engine runs it in.

:func:`compute` is that work, given the session's folder (:func:`app.store.workspace.materialise` wrote it): no
database, no blob store.  :func:`app.jobs.work.run_job` calls it in the job's own thread (a Celery worker: a
process of its own already) or, given a :class:`JobProcess`, in that helper.

**Why a process** (issue 16 finding 10h, measured with ``py-spy record --gil`` on ``chakamo serve`` during
``python -m benchmarks.load --backend inprocess``): the computation is Python and numpy that holds the
interpreter's lock for most of a job's ~10 s of CPU.  In the API process' own job threads it took about half of
the samples where any thread held that lock, and every request thread — each of its database calls gives the lock
up and must take it back — queued behind it; nor could the operating system favour the requests, because the
job threads and the request threads are one process (a job thread given a lower priority holds the interpreter's
lock and the database's write lock at that priority: every request then waits on the least favoured thread of
the machine).  A :class:`JobProcess` is a warm helper process (spawned; it imports the pipeline and the report
modules and loads the orientation filter's kernels once, :func:`app.pipeline.render.warm_up`) at the background
priority of the upload checks' helpers (:data:`app.pipeline.render.BACKGROUND_NICE`), which exits with the
server.  The job thread keeps everything that takes a lock: the database writes (progress, the stored analysis)
and the blob store; it relays the helper's progress calls to the job row (one pipe, read while it waits).  The
helper holds no lock of the server's, so its low priority delays nobody but itself.

A helper that dies under a job (killed, out of memory) is replaced and the job fails with the internal error's
sentence (:class:`HelperDied`; it may be what killed the helper: not run again by itself).  The artefacts are
rendered in the helper too, one after another (no render process beside it: the helper is the background).
No time limit: at the background priority on a machine busy with other work a job may take long, and it goes
on rather than fail (its heartbeat, written by the job thread, says it is alive).
"""

from __future__ import annotations

import logging
import os
from concurrent.futures import CancelledError
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from app.pipeline.render import RenderPool, exit_with_parent, warm_up

log = logging.getLogger("chakamo.jobs")

#: how often the job thread looks at the helper's answer while relaying its progress (seconds)
RELAY_EVERY_S = 0.25


def compute(folder: Path, options, lang: str, session_id: int, paired_id: int | None,
            progress) -> tuple[dict, dict[tuple[str, str], bytes]]:
    """``(results, files)`` of the session in ``folder`` processed with ``options`` (a
    :class:`app.pipeline.session.ProcessOptions`): ``results.json``'s content (the server's folder replaced by
    ``session {session_id}``, :func:`public_results`) and every artefact ``{(name, lang): bytes}``
    (:func:`app.pipeline.render.render_all`, reports in ``lang`` first).  ``progress(stage, fraction)`` is told
    each step.  Raises :class:`~app.pipeline.ingestion.IngestionError` or
    :class:`~app.pipeline.session.PipelineError` for data that cannot be processed."""
    from app.pipeline.ingestion import load_knees
    from app.pipeline.knees import process_knees
    from app.pipeline.render import PIPELINE_SHARE, render_all
    from app.pipeline.results import build_knees_results

    loaded = load_knees(folder)
    knees = process_knees(loaded, options, web=True,
                          progress=lambda st, f: progress(st, 0.02 + (PIPELINE_SHARE - 0.02) * f))
    results = public_results(build_knees_results(knees), session_id, paired_id)
    files = render_all(knees.primary, results, lang, progress, knees=knees)
    return results, files


def public_results(results: dict, session_id: int, paired_id: int | None = None) -> dict:
    """results.json without the server's temporary folder in it (in each knee's part too); a paired session's
    provenance names its partner (``session.paired_session_id``: the session the other knee's files came from)."""
    for part in [results, *(results.get("knees") or {}).values()]:
        sess = part.get("session", {})
        sess["folder"] = f"session {session_id}"
        if paired_id is not None:
            sess["paired_session_id"] = paired_id
        for src in sess.get("recognised", {}).values():
            if isinstance(src, dict) and "files" in src:
                src["files"] = [Path(f).name for f in src["files"]]
    return results


class HelperDied(RuntimeError):
    """The job's helper process ended under it (it has been replaced)."""


class HelperStopped(RuntimeError):
    """The server stopped the job's helper under it (:meth:`JobProcess.shutdown`): the job is not failed, it
    resumes at the next start."""


_progress_pipe = None  # in a helper: the write end of its progress pipe (set by _helper_start)


def _helper_start(parent_pid: int, pipe) -> None:
    """A helper's initializer: background priority, exit with the server, keep the progress pipe."""
    global _progress_pipe
    exit_with_parent(parent_pid)
    _progress_pipe = pipe


def _send_progress(stage: str, fraction: float) -> None:
    _progress_pipe.send((stage, fraction))


def _compute_here(folder: Path, options, lang: str, session_id: int, paired_id: int | None):
    """:func:`compute` in the helper, its progress sent through the pipe."""
    return compute(folder, options, lang, session_id, paired_id, _send_progress)


class JobProcess(RenderPool):
    """One warm helper process running one job's :func:`compute` at a time (module docstring); the embedded
    engine gives each job thread its own.  A :class:`~app.pipeline.render.RenderPool` of one (its start, warm-up,
    :meth:`restart` and :meth:`shutdown`) with a progress pipe from the helper.  After :meth:`shutdown` (the
    server stopping) the job thread gets :class:`HelperStopped` and leaves the job to resume at the next start."""

    def __init__(self) -> None:
        super().__init__(1, warm=warm_up)

    def _initializer(self, ctx):
        """The helper's initializer (:func:`_helper_start`) with a fresh progress pipe (one per helper)."""
        self._progress, self._progress_w = ctx.Pipe(duplex=False)
        return _helper_start, (os.getpid(), self._progress_w)

    @property
    def pid(self) -> int | None:
        """The helper's process id (None before it started)."""
        procs = list(getattr(self._pool, "_processes", {}) or {})
        return procs[0] if procs else None

    def run(self, progress, folder: Path, options, lang: str, session_id: int, paired_id: int | None):
        """:func:`compute` in the helper, its ``progress`` calls made here (in the calling thread, which may write
        them to the database); its exceptions are raised here.  :class:`HelperDied` when the helper ended under
        it (replaced); :class:`HelperStopped` when :meth:`shutdown` stopped it.

        A helper found dead before the job (it died while idle: killed, out of memory) is replaced and the job
        submitted to the new one — not this job's doing, so not its failure.  If the relay of the progress raises
        (the job was superseded, the database failed), the helper is replaced before the exception goes on: left
        computing, it would hold up the next job and send that job its own progress."""
        args = (_compute_here, folder, options, lang, session_id, paired_id)
        try:
            if self._stopping:
                raise HelperStopped("the job helper process was stopped")
            if not self._alive():
                raise BrokenProcessPool("the job helper process is gone")
            future = self._pool.submit(*args)
        except BrokenProcessPool:
            log.warning("the idle job helper process had ended; starting a new one")
            self.restart()
            if self._stopping:  # shutdown() came meanwhile: restart() did nothing, the pool is gone
                raise HelperStopped("the job helper process was stopped") from None
            future = self._pool.submit(*args)
        try:
            while not future.done():
                self._relay(progress, RELAY_EVERY_S)
            self._relay(progress, 0.0)
        except BaseException:
            if self._stopping:
                raise HelperStopped("the job helper process was stopped") from None
            self.restart()  # the helper would go on with an abandoned job
            raise
        try:
            return future.result()
        except (BrokenProcessPool, CancelledError):
            if self._stopping:
                raise HelperStopped("the job helper process was stopped") from None
            log.error("the job helper process ended under a job; starting a new one")
            self.restart()
            raise HelperDied("the job helper process ended") from None

    def _relay(self, progress, wait_s: float) -> None:
        while self._progress.poll(wait_s):
            try:
                stage, fraction = self._progress.recv()
            except (EOFError, OSError):
                return
            progress(stage, fraction)
            wait_s = 0.0

    def _stop(self) -> None:
        """Terminate the helper, drop its pool and close the progress pipe."""
        super()._stop()
        self._progress.close()
        self._progress_w.close()


__all__ = ["HelperDied", "HelperStopped", "JobProcess", "RELAY_EVERY_S", "compute"]
