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
from app.pipeline.ingestion import load_session
from app.pipeline.session import Progress, ProcessOptions, SessionOutcome, _no_progress, process_session
from app.pipeline.results import build_results, report_input, results_json, timeseries_npz, write_outputs


def process_folder(session_dir: str | os.PathLike, out_dir: str | os.PathLike, options: ProcessOptions | None = None,
                   *, progress: Progress = _no_progress, reports: bool = True) -> tuple[SessionOutcome, list[Path]]:
    """Read ``session_dir``, compute everything, render every output, then write them all into ``out_dir``.

    ``reports=False`` writes only ``results.json`` and ``timeseries.npz`` (no PDF, Excel, HTML or scene).

    Raises :class:`app.pipeline.ingestion.IngestionError` or :class:`app.pipeline.session.PipelineError` (both
    ``ValueError``) with a message for the user; nothing is written then.
    """
    options = options or ProcessOptions()
    progress("read", 0.0)
    with timings.stage("read"):
        session = load_session(session_dir, expected_fs_hz=options.expected_fs_hz)
    with timings.stage("pipeline"):
        outcome = process_session(session, options, progress=progress)
        results = build_results(outcome)
        files = {"results.json": results_json(results), "timeseries.npz": timeseries_npz(outcome)}
    if reports:  # imported here: matplotlib, plotly and viser cost ~80 MB a process that needs no report
        with timings.stage("imports"):
            from reports.excel import write_angles_xlsx, write_quaternions_xlsx
            from reports.html import render_html
            from reports.pdf import render_pdf
            from reports.scene import scene_bytes

        progress("reports", 0.97)
        with timings.stage("reports"):
            ri = report_input(outcome, results)
            with timings.stage("report.pdf"):
                pdf = render_pdf(ri)
            with timings.stage("report.html"):
                html = render_html(ri)
            with timings.stage("scene.viser"):
                scene = scene_bytes(ri)
        files |= {
            "report.pdf": pdf,
            "angles.xlsx": lambda path: write_angles_xlsx(ri, path),
            "quaternions.xlsx": lambda path: write_quaternions_xlsx(ri, path),
            "report.html": html,
            "scene.viser": scene,
        }
    progress("write", 0.99)
    with timings.stage("write"):  # the workbooks are rendered as they are written
        written = write_outputs(out_dir, files)
    progress("done", 1.0)
    return outcome, written
