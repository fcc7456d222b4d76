"""The ``chakamo process`` job: load a session folder, process it, write its outputs (all or nothing).

Outputs: ``results.json`` (DESIGN §4), ``timeseries.npz`` (the task's angles and orientations),
``report.pdf`` (the clinical report in the chosen language), ``angles.xlsx`` and ``quaternions.xlsx``,
``report.html`` (interactive, self-contained) and ``scene.viser`` (the recorded 3D femur-tibia
animation, played by viser's bundled client or ``chakamo view``).

The CLI, the demo and (later) the web application's job runner call :func:`process_folder`, so the
demo's simulated session goes through exactly the code path of a real one.
"""

from __future__ import annotations

import os
from pathlib import Path

from app.pipeline import timings
from app.pipeline.comparison import comparison
from app.pipeline.ingestion import load_knees
from app.pipeline.knees import process_knees
from app.pipeline.session import PipelineError, Progress, ProcessOptions, SessionOutcome, _no_progress
from app.pipeline.render import ForkedRenderers, render_named
from app.pipeline.results import build_knees_results, report_input, results_json, timeseries_npz, write_outputs

#: the rendered outputs, in the order they are written (after results.json); the same as
#: :data:`app.pipeline.render.FORK_GROUPS` together (the series too: its compression is off the parent's path)
REPORT_FILES = ("timeseries.npz", "report.pdf", "angles.xlsx", "quaternions.xlsx", "report.html", "scene.viser")


def load_kernels(filter_name: str) -> None:
    """Load the compiled kernels of filter ``filter_name`` (numba's on-disk cache) by running it once on one
    second of still 9D data; the first kernel a process loads also sets up numba itself (~0.4 s CPU, a third of
    it ``scipy.linalg``'s import, which numba makes to find BLAS).  The same calls as a session's (float64,
    C-contiguous, the same code path), so nothing is compiled anew and the session's run finds them loaded.
    The result is thrown away: no state is kept between runs."""
    import numpy as np

    from estimators.orientation import make

    n = 100
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    mag = np.tile([0.0, 20.0, -40.0], (n, 1))
    make(filter_name).estimate(acc, np.zeros((n, 3)), mag, fs_hz=100.0)


def _earlier_results(path: str | os.PathLike) -> dict:
    """The ``results.json`` of ``--compare-with`` (a file or the output folder holding one); a
    :class:`PipelineError` naming it when it cannot be read as one."""
    import json

    p = Path(path)
    p = p / "results.json" if p.is_dir() else p
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise PipelineError("pipeline.compare_unreadable", file=str(p), reason=str(exc)[:200]) from None
    if not isinstance(data, dict) or "rom_deg" not in data:
        raise PipelineError("pipeline.compare_unreadable", file=str(p), reason="no rom_deg")
    return data


def process_folder(session_dir: str | os.PathLike, out_dir: str | os.PathLike, options: ProcessOptions | None = None,
                   *, progress: Progress = _no_progress, reports: bool = True,
                   renderer: ForkedRenderers | None = None,
                   compare_with: str | os.PathLike | None = None) -> tuple[SessionOutcome, list[Path]]:
    """Read ``session_dir``, compute everything, render every output, then write them all into ``out_dir``.

    A folder of both knees (:func:`app.pipeline.ingestion.load_knees`) processes each; ``results.json`` then has
    both (:func:`app.pipeline.results.build_knees_results`) and the returned outcome is its top-level knee's.

    ``reports=False`` writes only ``results.json`` and ``timeseries.npz`` (no PDF, Excel, HTML or scene).
    ``compare_with``: an earlier analysis' ``results.json`` (or the folder holding it): ``results.json`` then gains
    ``comparison`` (:func:`app.pipeline.comparison.comparison`) and the reports a comparison section.
    ``renderer``: render processes forked at the command's start (:class:`app.pipeline.render.ForkedRenderers`,
    the CLI's cold start); without one every output is rendered here.  The bytes are the same either way.

    Raises :class:`app.pipeline.ingestion.IngestionError` or :class:`app.pipeline.session.PipelineError` (both
    ``ValueError``) with a message for the user; nothing is written then.
    """
    options = options or ProcessOptions()
    earlier = None if compare_with is None else _earlier_results(compare_with)  # refused before any work
    progress("read", 0.0)
    session = None
    if renderer is not None and renderer.reading and not renderer.read_failed:  # meanwhile numba's kernels load
        with timings.stage("kernels"):
            load_kernels(options.filter_name)
        with timings.stage("read.wait"):
            session = renderer.session()
    if session is None:  # no helper, or it could not read: read here (and raise the error, if any)
        with timings.stage("read"):
            session = load_knees(session_dir, expected_fs_hz=options.expected_fs_hz)
    with timings.stage("pipeline"):
        knees = process_knees(session, options, progress=progress)
        outcome = knees.primary
        results = build_knees_results(knees)
        if earlier is not None:
            results["comparison"] = comparison(earlier, results)
        files = {"results.json": results_json(results)}
        if not reports:
            files["timeseries.npz"] = timeseries_npz(outcome, knees)
    if reports:  # rendered with deferred imports: matplotlib, plotly and viser cost ~80 MB a process that needs no report
        progress("reports", 0.97)
        with timings.stage("reports"):
            ri = report_input(outcome, results, knees=knees)
            rendered = renderer.render(ri) if renderer is not None else render_named(ri, REPORT_FILES)
        files |= {name: rendered[name] for name in REPORT_FILES}
    progress("write", 0.99)
    with timings.stage("write"):
        written = write_outputs(out_dir, files)
    progress("done", 1.0)
    return outcome, written
