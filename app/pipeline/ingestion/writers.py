"""Write a whole simulated session as MetaBase exports (for ``chakamo demo`` and tests).

Real-world quirks are the caller's choice through the stamps it passes (different start milliseconds
per stream, 20 Hz magnetometer, a stream running on after the others, clock drift = stamps spaced by the
sensor's true period); this module adds the file-level ones: header dialect, ``:`` or ``.`` in the time
string, thesis-style labels in Spanish, English or Portuguese, and an optional ``session.json``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Mapping

from numpy.typing import ArrayLike

from app.pipeline.files import write_text_atomic
from app.pipeline.ingestion.metabase import write_recording_metabase
from app.pipeline.ingestion.model import ROLES, SEGMENTS

#: Words used in written labels, per language.
LABEL_WORDS = {
    "es": {"mag_calibration": "calibracion-sensor", "standing": "standing", "lying": "laydown", "task": "step",
           "thigh": "muslo", "shank": "pierna"},
    "en": {"mag_calibration": "calibration", "standing": "standing", "lying": "lying", "task": "task",
           "thigh": "thigh", "shank": "shank"},
    "pt": {"mag_calibration": "calibração", "standing": "em pé", "lying": "deitado", "task": "degrau",
           "thigh": "coxa", "shank": "perna"},
}
DEFAULT_MACS = {"thigh": "D4F1A2B3C4E5", "shank": "E8C2B1A0F9D7"}


def simulated_streams(imu, epoch0_s: float, *, run_on_s: Mapping[str, float] | None = None) -> dict:
    """``{kind: (t_s, values)}`` of an :class:`estimators.simulation.SimulatedImu` as the phone stamps it.

    The phone clock is the true time, so the stamps are ``epoch0_s + t_true_s`` (a sensor whose clock drifts
    delivers its samples at its true, drifted rate).  ``run_on_s`` drops the *other* streams' last seconds,
    e.g. ``{"gyr": 1.5}`` makes the gyroscope run on 1.5 s after the accelerometer and magnetometer stopped.
    """
    out = {k: (epoch0_s + s.t_true_s, s.values) for k, s in (("acc", imu.acc), ("gyr", imu.gyr), ("mag", imu.mag))}
    for kind, extra_s in (run_on_s or {}).items():
        t_end = out[kind][0][-1] - extra_s
        for other, (t, v) in list(out.items()):
            if other != kind:
                out[other] = (t[t <= t_end], v[t <= t_end])
    return out


def session_label(segment: str, role: str, patient_id: str, date_ddmmyyyy: str, trial: int = 1,
                  high_step: bool = False, lang: str = "es") -> str:
    """Thesis-style label ``{role}-{segment}-{ID}-{ddmmyyyy}-{n}[-H]`` in ``lang`` (es/en/pt)."""
    w = LABEL_WORDS[lang]
    h = "-H" if high_step and role == "task" else ""
    return f"{w[role]}-{w[segment]}-{patient_id}-{date_ddmmyyyy}-{trial}{h}".replace(" ", "-")


def write_session_metabase(folder: str | os.PathLike,
                           recordings: Mapping[tuple[str, str], Mapping[str, tuple[ArrayLike, ArrayLike]]], *,
                           patient_id: str = "DEMO1", date_ddmmyyyy: str = "13032023", high_step: bool = False,
                           lang: str = "es", macs: Mapping[str, str] | None = None, dialect: str = "epoch",
                           time_sep: str = ":", utc_offset_h: float = 0.0, manifest: Mapping | None = None,
                           rates_hz: Mapping[str, float] | None = None) -> list[Path]:
    """Write every recording of a session as MetaBase CSV files into ``folder`` (created if needed).

    recordings : ``{(segment, role): {"acc": (t_s, m/s²), "gyr": (t_s, rad/s), "mag": (t_s, µT)}}`` with
        ``t_s`` Unix seconds on the phone's clock (one clock for both sensors).
    manifest : if given, written as ``session.json`` (e.g. ``{"side": "left", "step_height_m": 0.17}``).
    Returns the files written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    macs = {**DEFAULT_MACS, **(macs or {})}
    out: list[Path] = []
    for (segment, role), streams in recordings.items():
        if segment not in SEGMENTS or role not in ROLES:
            raise ValueError(f"recording keys must be (segment in {SEGMENTS}, role in {ROLES}), got {(segment, role)}")
        label = session_label(segment, role, patient_id, date_ddmmyyyy, 1, high_step, lang)
        out += write_recording_metabase(folder, label, macs[segment], streams, rates_hz=rates_hz, dialect=dialect,
                                        time_sep=time_sep, utc_offset_h=utc_offset_h)
    if manifest is not None:
        out.append(write_text_atomic(folder / "session.json",
                                     json.dumps(dict(manifest), indent=2, ensure_ascii=False) + "\n"))
    return out
