"""Sensor Logger (phone app) zip export: one ``.zip`` per phone (sensor) × recording.

Layout (the app's "zip" export; its public units and cross-platform references)::

    Accelerometer.csv       time,seconds_elapsed,z,y,x     m/s², acceleration WITHOUT gravity
    TotalAcceleration.csv   time,seconds_elapsed,z,y,x     m/s², with gravity (Android only)
    Gravity.csv             time,seconds_elapsed,z,y,x     m/s², the gravity vector
    Gyroscope.csv           time,seconds_elapsed,z,y,x     rad/s
    Magnetometer.csv        time,seconds_elapsed,z,y,x     µT
    Metadata.csv            ...,device name,...,platform,...,device id,...   (optional; the sensor id: device id,
                            else the user-set device name)

``time`` is Unix epoch in **nanoseconds** (UTC; one clock for every sensor of the phone); the columns are
picked by name.  Specific force (what ChakaMo's ``acc`` is): ``TotalAcceleration`` when present; else
``Accelerometer + Gravity`` (Gravity interpolated on the accelerometer's stamps), which is the specific force
in the Android frame (gravity +z with the phone flat).  iOS without the app's "Standardise Units & Frames"
setting (its default) negates acceleration and gravity on every axis: with ``platform`` iOS in
``Metadata.csv`` the sum is negated back, and a note says the default setting was assumed (a recording made
with the setting on would have the opposite sign: record with the setting off, or say so in session.json).
The files may sit at the zip's root or in one folder inside it.
The size caps of :mod:`.phyphox`'s zips hold here too (:func:`.phyphox.check_zip`, :func:`.phyphox.read_member`):
a 10-minute 100 Hz sensor file takes ~5 MB.
"""

from __future__ import annotations

import io
import os
import zipfile
from pathlib import Path

import numpy as np

from app.pipeline.ingestion.phyphox import check_zip, read_member
from app.pipeline.ingestion.model import IngestionError, Note, Stream, rows_all
from app.pipeline.ingestion.tables import check_stamps, numeric_columns, parse_table
from app.pipeline.ingestion.units import check_magnitude

_NEEDED = ("Gyroscope.csv", "Magnetometer.csv")
_KNOWN = ("Accelerometer.csv", "TotalAcceleration.csv", "Gravity.csv", "Gyroscope.csv", "Magnetometer.csv")


def _members(z: zipfile.ZipFile) -> dict[str, str]:
    """``{file name: member path}`` of the CSV files (root or one folder deep)."""
    out: dict[str, str] = {}
    for name in z.namelist():
        base = name.rsplit("/", 1)[-1]
        if base.lower().endswith(".csv") and name.count("/") <= 1:
            out.setdefault(base, name)
    return out


def looks_like_sensorlogger(path: Path) -> bool:
    try:
        with zipfile.ZipFile(path) as z:
            m = _members(z)
    except (zipfile.BadZipFile, OSError):
        return False
    return any(n in m for n in _KNOWN)      # a sensor file missing is then refused by name, not skipped


def _table(path: Path, z: zipfile.ZipFile, member: str, notes: list) -> tuple[np.ndarray, np.ndarray, str]:
    """``(t_s epoch, values (n, 3) in file order x, y, z, header text)`` of one sensor file."""
    try:
        text = read_member(path, z, member).decode("utf-8-sig")
    except (UnicodeDecodeError, zipfile.BadZipFile, OSError) as exc:
        raise IngestionError("phone.member_unreadable", file=path, member=member, reason=str(exc)[:120]) from None
    header, rows = parse_table(path, text, notes)
    names = [h.strip().lower() for h in header]
    missing = [c for c in ("time", "x", "y", "z") if c not in names]
    if missing:
        raise IngestionError("phone.columns_missing", file=path, member=member, columns=", ".join(missing))
    t_ns = numeric_columns(path, header, rows, [names.index("time")], max_abs=1e20)[:, 0]  # ns: beyond 1e15
    data = numeric_columns(path, header, rows, [names.index(c) for c in ("x", "y", "z")])
    return t_ns * 1e-9, data, member


def _metadata(path: Path, z: zipfile.ZipFile, members: dict[str, str]) -> dict[str, str]:
    if "Metadata.csv" not in members:
        return {}
    try:
        lines = read_member(path, z, members["Metadata.csv"]).decode("utf-8-sig", "replace").splitlines()
    except (zipfile.BadZipFile, OSError):
        return {}
    if len(lines) < 2:
        return {}
    import csv
    head, row = next(csv.reader(io.StringIO(lines[0]))), next(csv.reader(io.StringIO(lines[1])))
    return {h.strip().lower(): v.strip() for h, v in zip(head, row)}


def read_sensorlogger(path: str | os.PathLike) -> tuple[Stream, Stream, Stream, str | None]:
    """Read a Sensor Logger zip → ``(acc specific force m/s², gyr rad/s, mag µT, device id or name)``, epoch s."""
    path = Path(path)
    try:
        z = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise IngestionError("phone.not_a_zip", file=path, reason=str(exc)[:120]) from None
    notes: list = []
    with z:
        members = _members(z)
        missing = [n for n in _NEEDED if n not in members]
        if "TotalAcceleration.csv" not in members and not {"Accelerometer.csv", "Gravity.csv"} <= set(members):
            missing.append("TotalAcceleration.csv (or Accelerometer.csv + Gravity.csv)")
        if missing:
            raise IngestionError("phone.files_missing", file=path, files=", ".join(missing))
        check_zip(path, z, [members[n] for n in (*_KNOWN, "Metadata.csv") if n in members])  # phyphox's caps
        meta = _metadata(path, z, members)
        ios = meta.get("platform", "").lower() == "ios"
        if "TotalAcceleration.csv" in members:
            t_a, acc, src = _table(path, z, members["TotalAcceleration.csv"], notes)
        else:
            t_a, lin, src = _table(path, z, members["Accelerometer.csv"], notes)
            t_g, grav, _ = _table(path, z, members["Gravity.csv"], notes)
            ok = rows_all(np.isfinite(grav))
            if ok.sum() < 2:
                raise IngestionError("stream.all_empty", file=path)
            acc = lin + np.stack([np.interp(t_a, t_g[ok], grav[ok, i]) for i in range(3)], axis=1)
            if ios:
                acc = -acc
                notes.append(Note.of("phone_ios_frames", file=path.name))
        t_g2, gyr, _ = _table(path, z, members["Gyroscope.csv"], notes)
        t_m, mag, _ = _table(path, z, members["Magnetometer.csv"], notes)
    streams = []
    for kind, t, v, unit in (("acc", t_a, acc, "m/s2"), ("gyr", t_g2, gyr, "rad/s"), ("mag", t_m, mag, "uT")):
        check_stamps(path, t, f"{kind}: time")
        check_magnitude(kind, v, unit, path)
        streams.append(Stream(kind=kind, t_s=t, values=v, declared_unit=unit, file=path,
                              notes=tuple(dict.fromkeys(notes)) if kind == "acc" else ()))
    # the app's own id of the phone first (a serial); the user-set device name only when there is none
    device = meta.get("device id") or meta.get("deviceid") or meta.get("device name") or meta.get("devicename") \
        or meta.get("device") or None
    return streams[0], streams[1], streams[2], device


def write_sensorlogger(path: str | os.PathLike, streams: dict, *, platform: str = "android",
                       total: bool = True, device_id: str | None = None) -> Path:
    """Write a Sensor Logger-style zip (tests, demo).  ``streams`` ``{"acc": (t_s, specific force m/s²),
    "gyr": (t_s, rad/s), "mag": (t_s, µT)}``.  ``total``: a TotalAcceleration.csv (Android); else
    Accelerometer.csv (without gravity) + Gravity.csv (a low-passed specific force), negated for iOS.
    ``device_id``: a ``device id`` column in Metadata.csv (newer app versions); None: the device name only."""
    path = Path(path)

    def table(t, v):
        lines = ["time,seconds_elapsed,z,y,x"]
        t0 = t[0]
        for k in range(len(t)):
            lines.append(f"{int(round(t[k] * 1e9))},{t[k] - t0:.6f},{v[k, 2]:.6f},{v[k, 1]:.6f},{v[k, 0]:.6f}")
        return "\n".join(lines) + "\n"

    t, f = streams["acc"]
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        if total:
            z.writestr("TotalAcceleration.csv", table(t, f))
        else:
            n = max(1, int(round(0.5 / np.median(np.diff(t)))))
            kernel = np.ones(n) / n
            g = np.stack([np.convolve(np.pad(f[:, i], (n, n), mode="edge"), kernel, mode="same")[n:-n]
                          for i in range(3)], axis=1)
            sign = -1.0 if platform == "ios" else 1.0
            z.writestr("Accelerometer.csv", table(t, sign * (f - g)))
            z.writestr("Gravity.csv", table(t, sign * g))
        z.writestr("Gyroscope.csv", table(*streams["gyr"]))
        z.writestr("Magnetometer.csv", table(*streams["mag"]))
        extra = (",device id", f",{device_id}") if device_id else ("", "")
        z.writestr("Metadata.csv", f"version,device name,recording time,platform{extra[0]}\n3,Pixel 7,"
                                   f"2023-03-13_10-00-00,{platform}{extra[1]}\n")
    return path
