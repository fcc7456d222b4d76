"""The ``chakamo process`` job: load a session folder, process it, write its outputs (all or nothing).

The CLI, the demo and (later) the web application's job runner call :func:`process_folder`, so the
demo's simulated session goes through exactly the code path of a real one.
"""

from __future__ import annotations

import os
from pathlib import Path

from app.ingestion import load_session
from app.pipeline import Progress, ProcessOptions, SessionOutcome, _no_progress, process_session
from app.results import results_json, timeseries_npz, write_outputs


def process_folder(session_dir: str | os.PathLike, out_dir: str | os.PathLike, options: ProcessOptions | None = None,
                   *, progress: Progress = _no_progress) -> tuple[SessionOutcome, list[Path]]:
    """Read ``session_dir``, compute everything, then write ``results.json`` and ``timeseries.npz`` into ``out_dir``.

    Raises :class:`app.ingestion.IngestionError` or :class:`app.pipeline.PipelineError` (both
    ``ValueError``) with a message for the user; nothing is written then.
    """
    options = options or ProcessOptions()
    progress("read", 0.0)
    session = load_session(session_dir, expected_fs_hz=options.expected_fs_hz)
    outcome = process_session(session, options, progress=progress)
    written = write_outputs(out_dir, {"results.json": results_json(outcome), "timeseries.npz": timeseries_npz(outcome)})
    return outcome, written
