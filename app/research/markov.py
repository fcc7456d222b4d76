"""``chakamo markov``: Markovian Kalman filters on a research CSV of several segment IMUs.

Input CSV format (one file, comma-separated, a header row; lines starting with ``#`` are ignored)
-----------------------------------------------------------------------------------------------
=========================== ================================================================
column                      meaning
=========================== ================================================================
``t_s``                     time, s, uniform sampling (the rate is taken from its median step)
``<seg>_acc_x|y|z``         accelerometer of segment ``<seg>``, m/s² (specific force, +9.81 up)
``<seg>_gyr_x|y|z``         gyroscope of segment ``<seg>``, rad/s
``<joint>_enc_rad``         optional encoder angle, rad; empty cells where it has no sample
=========================== ================================================================

``<seg>`` is any run of consecutive segments of ``trunk, thigh, shank, foot`` (at least two), proximal
first; ``<joint>`` is ``hip`` (trunk–thigh), ``knee`` (thigh–shank) or ``ankle`` (shank–foot), the angle
of the proximal segment minus the distal one about the joint axis.  All sensors are mounted so that the
joints turn about the same sensor axis (``joint_axis``, default ``x`` as in seed 000: "roll" is the
sagittal angle).  **The record must start with the limb still in the reference pose** (e.g. standing
upright, segments vertical): the first ``still_s`` seconds define zero of every angle.

Methods: ``mjls`` (planar MKF, seed 002; encoders used when present), ``kf`` (the standard per-segment
KF beside it), ``sme`` (spatial, needs the encoders), ``smea`` (thigh + shank only, no encoder: the
self-aligned knee angle); ``auto`` = ``sme`` when every joint has an encoder column, otherwise ``smea``
for thigh + shank, otherwise ``kf``.

Output in ``out``: ``angles.csv`` (``t_s``, ``<seg>_<angle>_deg`` — ``sagittal`` for the planar methods,
``roll, pitch, yaw`` about sensor x, y, z for the spatial ones —, ``<joint>_deg``, ``markov_state``) and
``markov.json`` (method, parameters, rate, Markov state occupancy and accelerometer use, as fractions).
"""

from __future__ import annotations

import csv
import json
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from app.choices import MARKOV_METHODS
from estimators.markov.fkc import accelerometer_angles
from estimators.markov.mjls import MjlsParams, mkf, standard_kf
from estimators.markov.sme import SpatialParams, sme
from estimators.markov.smea import smea

__all__ = ["run_markov", "read_markov_csv", "SEGMENTS", "JOINTS", "METHODS"]

SEGMENTS = ("trunk", "thigh", "shank", "foot")
JOINTS = ("hip", "knee", "ankle")
METHODS = MARKOV_METHODS  # one definition: app.choices
_AXES = {"x": 0, "y": 1, "z": 2}


def read_markov_csv(path: str | Path) -> dict:
    """Read the CSV described in the module docstring → dict with ``t_s``, ``segments`` (names),
    ``acc``/``gyr`` (lists of (N, 3)), ``encoders`` ({joint: (N,)} with NaN gaps), ``fs_hz``."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    with path.open(newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    if len(rows) < 3:
        raise ValueError(f"{path}: needs a header row and at least two data rows")
    header = [h.strip() for h in rows[0]]
    col = {h: i for i, h in enumerate(header)}
    if "t_s" not in col:
        raise ValueError(f"{path}: missing column 't_s' (time, s)")

    def column(name: str) -> np.ndarray:
        vals = [r[col[name]].strip() if col[name] < len(r) else "" for r in rows[1:]]
        try:
            return np.array([float(v) if v else np.nan for v in vals])
        except ValueError as exc:
            raise ValueError(f"{path}: column {name!r} holds a non-number ({exc})") from None

    present = [s for s in SEGMENTS if all(f"{s}_{k}_{a}" in col for k in ("acc", "gyr") for a in "xyz")]
    partial = [s for s in SEGMENTS if s not in present and any(h.startswith(s + "_") for h in header)]
    if partial:
        raise ValueError(f"{path}: segment(s) {partial} lack some of the columns <seg>_acc_x..z, <seg>_gyr_x..z")
    if len(present) < 2:
        raise ValueError(f"{path}: need IMU columns of at least two segments out of {SEGMENTS}, found {present}")
    idx = [SEGMENTS.index(s) for s in present]
    if idx != list(range(idx[0], idx[0] + len(idx))):
        raise ValueError(f"{path}: segments must be consecutive ({', '.join(SEGMENTS)}), found {present}")
    t = column("t_s")
    dt = np.diff(t)
    if not np.all(np.isfinite(t)) or np.any(dt <= 0):
        raise ValueError(f"{path}: t_s must be finite and increasing")
    fs = 1.0 / float(np.median(dt))
    acc = [np.column_stack([column(f"{s}_acc_{a}") for a in "xyz"]) for s in present]
    gyr = [np.column_stack([column(f"{s}_gyr_{a}") for a in "xyz"]) for s in present]
    for s, a, g in zip(present, acc, gyr):
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(g))):
            raise ValueError(f"{path}: segment {s!r} has empty or non-finite IMU cells; fill or cut the gaps")
    joints = JOINTS[idx[0]:idx[0] + len(idx) - 1]
    enc = {j: column(f"{j}_enc_rad") for j in joints if f"{j}_enc_rad" in col}
    return {"t_s": t, "segments": present, "joints": joints, "acc": acc, "gyr": gyr, "encoders": enc, "fs_hz": fs}


def run_markov(path: str | Path, out: str | Path, *, method: str = "auto", zeta_g: float | None = None,
               joint_axis: str = "x", still_s: float = 1.0) -> dict:
    """Run a Markovian filter on ``path`` (CSV, module docstring) and write ``angles.csv`` and
    ``markov.json`` into ``out``.  Returns the summary written to ``markov.json``."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    if joint_axis not in _AXES:
        raise ValueError(f"joint_axis must be x, y or z, got {joint_axis!r}")
    if not (np.isfinite(still_s) and still_s > 0):
        raise ValueError(f"still_s must be > 0, got {still_s!r}")
    data = read_markov_csv(path)
    segs, joints, fs = data["segments"], data["joints"], data["fs_hz"]
    n = len(data["t_s"])
    ax = _AXES[joint_axis]
    all_enc = len(data["encoders"]) == len(joints)
    if method == "auto":
        method = "sme" if all_enc else ("smea" if segs == ["thigh", "shank"] else "kf")
    if method == "sme" and not all_enc:
        raise ValueError(f"method 'sme' needs an encoder column for every joint ({', '.join(joints)})")
    if method == "smea" and segs != ["thigh", "shank"]:
        raise ValueError(f"method 'smea' models thigh + shank only, the file has {segs}")
    n0 = max(1, min(n, int(round(still_s * fs))))
    gref = [a[:n0].mean(axis=0) for a in data["acc"]]
    enc = np.column_stack([data["encoders"].get(j, np.full(n, np.nan)) for j in joints])
    cols: dict[str, np.ndarray] = {"t_s": data["t_s"]}
    summary: dict = {"method": method, "fs_hz": fs, "segments": segs, "joints": list(joints),
                     "joint_axis": joint_axis, "samples": n}
    if method in ("mjls", "kf"):
        k = len(segs)
        base = MjlsParams()
        first = SEGMENTS.index(segs[0])          # Table 2 rows of the segments present
        p = replace(base, **{f: getattr(base, f)[first:first + k] for f in
                             ("q_angle_deg2_s", "q_bias_deg2_s3", "r_acc_deg2", "tau_gyro_s")})
        if zeta_g is not None:
            p = replace(p, zeta_g=zeta_g)
        w = np.column_stack([g[:, ax] for g in data["gyr"]])
        za = np.column_stack([accelerometer_angles(a, gr)[0][:, ax] for a, gr in zip(data["acc"], gref)])
        an = np.column_stack([np.linalg.norm(a, axis=1) for a in data["acc"]])
        r = mkf(w, za, an, enc, fs_hz=fs, params=p, theta0_rad=np.zeros(k)) if method == "mjls" else \
            standard_kf(w, za, an, fs_hz=fs, params=p, theta0_rad=np.zeros(k))
        for i, s in enumerate(segs):
            cols[f"{s}_sagittal_deg"] = np.degrees(r.theta_rad[:, i])
        joint_rad, state, used = r.joint_rad, r.markov_state, r.corrected
        summary["params"] = asdict(p)
        labels = segs
        summary["corrected"] = float(np.mean(used))
    else:
        p = SpatialParams(joint_axis=ax)
        if zeta_g is not None:
            p = replace(p, zeta_g=zeta_g)
        th0 = np.zeros(3 * len(segs))
        if method == "sme":
            r = sme(data["gyr"], data["acc"], enc, fs_hz=fs, params=p, gravity_ref=gref, theta0_rad=th0)
            labels = segs
        else:
            r = smea(data["gyr"], data["acc"], fs_hz=fs, params=p, gravity_ref=gref, theta0_rad=th0)
            labels = segs + ["thigh+shank"]
        for i, s in enumerate(segs):
            for a, name in enumerate(("roll", "pitch", "yaw")):
                cols[f"{s}_{name}_deg"] = np.degrees(r.theta_rad[:, i, a])
        joint_rad, state = r.joint_rad, r.markov_state
        summary["params"] = asdict(p)
        summary["accelerometer_use"] = {s: float(r.acc_used[:, i].mean()) for i, s in enumerate(segs)}
    for i, j in enumerate(joints):
        cols[f"{j}_deg"] = np.degrees(joint_rad[:, i])
    cols["markov_state"] = np.asarray(state)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = list(cols)
    with (out / "angles.csv").open("w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(names)
        for k in range(n):
            wr.writerow([f"{cols[c][k]:.6g}" if c != "markov_state" else int(cols[c][k]) for c in names])
    summary["params"] = {k: (list(v) if isinstance(v, tuple) else v) for k, v in summary["params"].items()}
    summary["occupancy"] = {s: float(np.mean(state == i)) for i, s in enumerate(labels)}
    summary["markov_state_labels"] = labels
    (out / "markov.json").write_text(json.dumps(summary, indent=2, default=float))
    return summary
