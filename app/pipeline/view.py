"""``chakamo view OUT_DIR``: the live 3D knee of a processed session in the browser (viser).

Reads what ``chakamo process`` wrote into ``OUT_DIR`` — ``results.json`` and ``timeseries.npz`` (keys
``t_s``, ``angles_deg``, ``q_earth_segment_femur``/``_tibia``, ``q_earth_sensor_thigh``/``_shank``,
optionally ``q_sensor_segment_thigh``/``_shank``) — builds the scene of :mod:`reports.scene` on a
``viser.ViserServer`` and plays it until Ctrl-C.  The server listens on 127.0.0.1:8080 by default
(only this machine); pass ``host="0.0.0.0"`` to show it on the clinic's network.
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import numpy as np

from reports.model import LANGUAGES, Patient, ReportInput

RESULTS_FILE = "results.json"
TIMESERIES_FILE = "timeseries.npz"
_REQUIRED_KEYS = ("t_s", "angles_deg", "q_earth_segment_femur", "q_earth_segment_tibia",
                  "q_earth_sensor_thigh", "q_earth_sensor_shank")


class ViewInputError(ValueError):
    """OUT_DIR does not hold a processed session the viewer can read (message says what to do)."""


def load_view_input(out_dir: str | os.PathLike, *, language: str | None = None) -> ReportInput:
    """The :class:`ReportInput` of a processed session folder (results.json + timeseries.npz).

    language: ``es``/``en``/``pt`` for the viewer's texts; default the session's language in
    results.json (``results["session"]["language"]``), else ``es``.
    Raises :class:`ViewInputError` when a file is missing, unreadable or incomplete.
    """
    out = Path(out_dir)
    hint = f"run `chakamo process SESSION_DIR --out {out}` first"
    results_path, series_path = out / RESULTS_FILE, out / TIMESERIES_FILE
    for path in (results_path, series_path):
        if not path.is_file():
            raise ViewInputError(f"{path} not found: {hint}")
    try:
        results = json.loads(results_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ViewInputError(f"{results_path} is not a readable results file ({exc}): {hint}") from exc
    if not isinstance(results, dict):
        raise ViewInputError(f"{results_path} is not a results object: {hint}")
    try:
        with np.load(series_path, allow_pickle=False) as npz:
            missing = [k for k in _REQUIRED_KEYS if k not in npz.files]
            if missing:
                raise ViewInputError(f"{series_path} lacks {', '.join(missing)}: {hint}")
            series = {k: np.asarray(npz[k], dtype=float) for k in npz.files}
    except ViewInputError:
        raise
    except Exception as exc:  # zip/npy format errors come as several exception types
        raise ViewInputError(f"{series_path} is not a readable time-series file ({exc}): {hint}") from exc

    session = results.get("session") if isinstance(results.get("session"), dict) else {}
    lang = language or session.get("language") or "es"
    if lang not in LANGUAGES:
        lang = "es"
    q_identity = np.array([1.0, 0.0, 0.0, 0.0])
    patient = Patient(name_or_id=str(session.get("patient_id") or ""), date=str(session.get("date") or ""),
                      side=str(results.get("side") or ""), step_height_m=session.get("step_height_m"))
    try:
        return ReportInput(
            results=results,
            t_s=series["t_s"],
            angles_deg=series["angles_deg"],
            q_earth_sensor={"thigh": series["q_earth_sensor_thigh"], "shank": series["q_earth_sensor_shank"]},
            q_earth_segment={"femur": series["q_earth_segment_femur"], "tibia": series["q_earth_segment_tibia"]},
            q_sensor_segment={"thigh": series.get("q_sensor_segment_thigh", q_identity),
                              "shank": series.get("q_sensor_segment_shank", q_identity)},
            patient=patient,
            language=lang,
        )
    except ValueError as exc:
        raise ViewInputError(f"{series_path}: {exc}: {hint}") from exc


def serve_view(out_dir: str | os.PathLike, *, host: str = "127.0.0.1", port: int = 8080,
               language: str | None = None, stop: threading.Event | None = None) -> None:
    """Serve the live 3D knee of ``out_dir`` until Ctrl-C (or until ``stop`` is set)."""
    import viser

    from reports.scene import build_scene

    ri = load_view_input(out_dir, language=language)
    server = viser.ViserServer(host=host, port=port, label="ChakaMo")
    try:
        scene = build_scene(server, ri)
        scene.run(stop)
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
