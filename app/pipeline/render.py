"""Artefact rendering: every output file of an analysis from one report input, and the warm render process.

:func:`render_all` builds ``results.json`` and ``timeseries.npz`` and renders ``report.pdf`` in every
language of :data:`reports.i18n.LANGUAGES`, ``angles.xlsx``, ``quaternions.xlsx``, ``report.html`` and
``scene.viser`` (:func:`render_artefact` is one of them).  With a :class:`RenderPool` (one warm helper
process, ``CHAKAMO_RENDER_PROCESSES``) the other-language PDFs and angles.xlsx are rendered there while the
job thread renders the rest; if the process fails, or gives no answer within ``timeout_s``
(``CHAKAMO_RENDER_TIMEOUT_S``), the job thread renders them itself and a hung process is replaced.
:func:`warm_up` imports the report modules and runs the default filter once, so a job never pays for that.
The job runner (:mod:`app.jobs.work`) calls :func:`render_all`; nothing here touches the database.
"""

from __future__ import annotations

import dataclasses
import logging
import os
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
}
#: share of the progress bar taken by the pipeline; the rest is the reports
PIPELINE_SHARE = 0.6
#: default longest wait for the render process (seconds)
RENDER_TIMEOUT_S = 300.0


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


def render_all(outcome, results: dict, lang: str, progress, pool: "RenderPool | None" = None,
               timeout_s: float = RENDER_TIMEOUT_S) -> dict[tuple[str, str], bytes]:
    """Every artefact from one report input: ``{(name, lang): bytes}`` (lang "" unless a PDF).

    With a warm :class:`RenderPool`, the two other-language PDFs and angles.xlsx are rendered in the
    render process while this thread renders the rest (the report code holds the GIL: threads would not
    overlap); without one, or if that process fails or does not answer within ``timeout_s``, everything is
    rendered here.  ``progress(stage, fraction)`` is told each step.
    """
    from app.pipeline.results import report_input, results_json, timeseries_npz

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
        progress(f"{name} {x}".strip(), PIPELINE_SHARE + (1 - PIPELINE_SHARE) * i / (len(local) + 1))
        files[(name, x)] = render_artefact(ri, name, x)
    if future is not None:
        progress("reports (render process)", 0.95)
        files |= collect(future, pool, timeout_s, lambda: render_many(ri, remote))
    return files


def collect(future, pool: "RenderPool | None", timeout_s: float, fallback):
    """The result of ``future`` from the render process, or ``fallback()`` (rendering in this thread) when
    the process failed or gave no answer within ``timeout_s`` — then the hung process is replaced."""
    try:
        return future.result(timeout=timeout_s)
    except FutureTimeout:  # a hung render process must not block this worker forever
        future.cancel()
        log.error("the render process did not answer within %.0f s; rendering in the job thread", timeout_s)
        if pool is not None:
            pool.restart()
        return fallback()
    except Exception:  # noqa: BLE001 — e.g. the render process died: render here instead
        log.exception("render process failed; rendering in the job thread")
        return fallback()


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
    one killed with SIGKILL), and is warmed up by ``warm`` (default :func:`warm_up`: the report modules);
    :meth:`submit` returns None until it is warm, so a job never waits for its start-up.  :meth:`restart`
    replaces a hung or dead process — only then: work that raised leaves the process as it is (the upload
    checks' helpers are pools of one, :class:`app.store.checks.CheckPool`).
    """

    def __init__(self, processes: int, warm=None) -> None:
        self.processes = processes
        self._warm_fn = warm or warm_up
        self._lock = threading.Lock()
        self._start()

    def _start(self) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self._pool = ProcessPoolExecutor(self.processes, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_exit_with_parent, initargs=(os.getpid(),))
        self._warm = self._pool.submit(self._warm_fn)

    def restart(self) -> None:
        """Replace a hung process by a fresh one (its work is abandoned; the caller renders it itself)."""
        with self._lock:
            old = self._pool
            for proc in list(getattr(old, "_processes", {}).values()):  # no public way to stop a hung worker
                proc.terminate()
            old.shutdown(wait=False, cancel_futures=True)
            self._start()

    def submit(self, fn, *args):
        """``fn(*args)`` in the render process, or None when it is not warm or not usable."""
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


def warm_up() -> None:
    """Before the first job needs them: import the processing and report modules (≈1 s), make the PDF's font
    cut (once per machine, ≈0.3 s) and run the default orientation filter once on one second of still data
    (loads its compiled numba kernels, ≈0.3 s)."""
    import importlib

    for name in ("app.pipeline.session", "app.pipeline.results", "reports.excel", "reports.html", "reports.pdf", "reports.scene"):
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


__all__ = ["LANGS", "MEDIA", "PIPELINE_SHARE", "RENDER_TIMEOUT_S", "RenderPool", "collect", "render_all",
           "render_artefact", "render_many", "warm_up"]
