"""APDM Opal HDF5 (``.h5``, Mobility Lab / Motion Studio file format version 5): several sensors per file.

Layout read::

    /                                   attribute FileFormatVersion (5)
    /Sensors/<id>/Accelerometer         (N, 3) m/s²   specific force
    /Sensors/<id>/Gyroscope             (N, 3) rad/s
    /Sensors/<id>/Magnetometer          (N, 3) µT
    /Sensors/<id>/Time                  (N,)   µs since 1970-01-01 UTC (uint64), one clock for every sensor
    /Sensors/<id>/Configuration         attributes "Label 0" (e.g. "Right Thigh"), "Sample Rate" (Hz)

Units are fixed by the format (SI already, µT); they are converted by :func:`.units.unit_factor` like any
declared unit, so the factors live in one place.  Each sensor of the file is one recording: its segment
(and side) come from its label, the role from the file name; ``session.json`` may pick a sensor with
``"sensor": "<id>"`` in a ``recordings`` entry.  Files of format version 3 (``/<case>/Calibrated/...``) are
refused with advice.  Needs ``h5py`` (imported when a ``.h5`` file is read).

Caps (the file may come from a web upload): a compressed dataset may declare any size, so each dataset's declared
shape is checked before a byte of it is read: ``(N,)`` stamps and ``(N, 3)`` values (another shape is a damaged
file, ``opal.bad_shape``), at most :data:`MAX_SAMPLES` samples (two hours at 200 Hz; a
recording of ``N`` samples then takes at most ``N · 3 · 8`` bytes a dataset once read as float64) and at most
:data:`MAX_SENSORS` sensors per file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from app.pipeline.ingestion.model import IngestionError, Stream
from app.pipeline.ingestion.tables import check_stamps
from app.pipeline.ingestion.units import check_magnitude, unit_factor

#: samples per dataset: 2 h at 200 Hz (Opals record at 20–128 Hz)
MAX_SAMPLES = 2 * 3600 * 200
#: sensors per file (a Mobility Lab system has at most a few dozen)
MAX_SENSORS = 64
_DATASETS = {"acc": ("Accelerometer", "m/s2"), "gyr": ("Gyroscope", "rad/s"), "mag": ("Magnetometer", "uT")}


def _h5py():
    try:
        import h5py
    except ImportError:  # pragma: no cover - a runtime dependency
        raise IngestionError("opal.no_h5py") from None
    return h5py


def _text(value) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        return _text(value.flat[0]) if value.size else ""
    return str(value)


def _open(path: Path):
    h5py = _h5py()
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise IngestionError("opal.cannot_open", file=path, reason=str(exc)[:160]) from None


def _check_apdm(path: Path, f) -> None:
    """Refuse an HDF5 file without ``/Sensors``: an older APDM file (it carries ``FileFormatVersion``) is asked to
    be exported again; any other HDF5 file (e.g. a dataset's own layout, like BROAD's ``imu_acc``…) is named as
    not an APDM recording, with what it holds."""
    if "Sensors" in f:
        return
    if "FileFormatVersion" in f.attrs:
        raise IngestionError("opal.not_v5", file=path)
    names = [n if len(n) <= 40 else n[:39] + "…" for n in sorted(f.keys())[:9]]   # a message, not a dump
    held = ", ".join(names[:8]) + (", …" if len(names) > 8 else "") if names else "-"
    raise IngestionError("opal.not_apdm", file=path, datasets=held)


def list_sensors(path: str | os.PathLike) -> dict[str, str]:
    """``{sensor id: label}`` of an APDM file (label ``""`` when the file gives none)."""
    path = Path(path)
    with _open(path) as f:
        _check_apdm(path, f)
        if len(f["Sensors"]) > MAX_SENSORS:
            raise IngestionError("opal.too_large", file=path, dataset="/Sensors", shape=str(len(f["Sensors"])),
                                 limit=MAX_SENSORS)
        out = {}
        for sid in f["Sensors"]:
            conf = f["Sensors"][sid].get("Configuration")
            out[str(sid)] = _text(conf.attrs.get("Label 0", "")) if conf is not None else ""
        return out


def read_opal(path: str | os.PathLike, sensor: str | None = None) -> tuple[Stream, Stream, Stream, str, str]:
    """One sensor of an APDM file → ``(acc, gyr, mag, sensor id, sensor label)`` in project units, epoch s.

    ``sensor`` may be omitted when the file holds one sensor."""
    path = Path(path)
    sensors = list_sensors(path)
    if sensor is None:
        if len(sensors) != 1:
            raise IngestionError("opal.which_sensor", file=path,
                                 sensors=", ".join(f"{k} ({v})" if v else k for k, v in sensors.items()) or "-")
        sensor = next(iter(sensors))
    if sensor not in sensors:
        raise IngestionError("opal.no_such_sensor", file=path, sensor=sensor, sensors=", ".join(sensors) or "-")
    with _open(path) as f:
        g = f["Sensors"][sensor]
        missing = [name for name, _ in _DATASETS.values() if name not in g] + ([] if "Time" in g else ["Time"])
        if missing:
            raise IngestionError("opal.datasets_missing", file=path, sensor=sensor, datasets=", ".join(missing))
        samples = (getattr(g["Time"], "shape", None) or (0,))[0]
        for name in ("Time", *(n for n, _ in _DATASETS.values())):   # declared shapes, before any byte is read
            shape = getattr(g[name], "shape", None) or ()
            expected = "(N,)" if name == "Time" else f"({samples}, 3)"
            if len(shape) != (1 if name == "Time" else 2) or (name != "Time" and shape[1] != 3):
                raise IngestionError("opal.bad_shape", file=path, dataset=f"/Sensors/{sensor}/{name}",
                                     shape=str(shape), expected=expected)
            if shape[0] > MAX_SAMPLES:
                raise IngestionError("opal.too_large", file=path, dataset=f"/Sensors/{sensor}/{name}",
                                     shape=str(shape), limit=MAX_SAMPLES)
        t_s = np.asarray(g["Time"][()], dtype=np.float64) * 1e-6
        conf = g.get("Configuration")
        rate = conf.attrs.get("Sample Rate") if conf is not None else None
        arrays = {k: np.asarray(g[name][()], dtype=np.float64) for k, (name, _) in _DATASETS.items()}
    check_stamps(path, t_s, f"/Sensors/{sensor}/Time", first_row=1)
    streams = []
    for kind, (name, unit) in _DATASETS.items():
        v = arrays[kind]
        if v.ndim != 2 or v.shape != (len(t_s), 3):
            raise IngestionError("opal.bad_shape", file=path, dataset=f"/Sensors/{sensor}/{name}",
                                 shape=str(v.shape), expected=f"({len(t_s)}, 3)")
        v = v * unit_factor(kind, unit)
        check_magnitude(kind, v, unit, path)
        streams.append(Stream(kind=kind, t_s=t_s, values=v, declared_unit=unit, file=path,
                              nominal_fs_hz=float(np.asarray(rate).flat[0]) if rate is not None else None))
    return streams[0], streams[1], streams[2], sensor, sensors[sensor]


def write_opal(path: str | os.PathLike, sensors: dict[str, dict]) -> Path:
    """Write an APDM-v5-style file (tests, demo).  ``sensors``: ``{id: {"label": "Right Thigh", "rate_hz": 128,
    "t_s": epoch s (N,), "acc": m/s², "gyr": rad/s, "mag": µT}}``."""
    h5py = _h5py()
    path = Path(path)
    with h5py.File(path, "w") as f:
        f.attrs["FileFormatVersion"] = 5
        for sid, s in sensors.items():
            g = f.create_group(f"Sensors/{sid}")
            g["Time"] = np.round(np.asarray(s["t_s"]) * 1e6).astype(np.uint64)
            for kind, (name, _) in _DATASETS.items():
                g[name] = np.asarray(s[kind], dtype=np.float64)
            conf = g.create_group("Configuration")
            conf.attrs["Label 0"] = s.get("label", "").encode()
            conf.attrs["Sample Rate"] = float(s.get("rate_hz", 128.0))
    return path
