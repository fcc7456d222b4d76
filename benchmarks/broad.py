r"""Accuracy on BROAD: total, heading and inclination RMSE against optical ground truth.

Usage
-----
``python -m benchmarks.broad [--mode 9d|6d|both] [--methods guo madgwick ...] [--trials 02 27 ...] [--no-ahrs]
[--jobs 2] [--json OUT]`` (about 2.5 min on one core, most of it the pure-Python ``ahrs`` rows; 2 s with ``--no-ahrs``)
prints, per mode, a summary (undisturbed trials 02–18, disturbed 24–35) and per-trial tables of every
method in ``estimators.orientation.METHODS`` (methods whose module is not written yet are skipped with a
note) beside the comparison rows of :mod:`benchmarks.baselines` (VQF offline/online, the ``ahrs``
package's Madgwick, FKF and AQUA) and BROAD's published Madgwick numbers.  From Python: ``trials()`` yields :class:`Trial` objects (``acc``,
``gyr``, ``mag``, ``quat_ref``, ``movement``, ``fs_hz``, ``name``, ``group``); ``broad_errors(q, trial)``
scores one estimate; ``evaluate(fn, mode="9d")`` scores ``fn(acc, gyr, mag_or_None, fs_hz) -> q_earth_sensor``
(ENU) on every trial and returns one row (a dict) per trial — the tool for tuning a filter.  The data is
looked up in ``$CHAKAMO_BROAD_DIR``, else ``../shared/data/broad`` next to the repository; when it is
absent ``trials()`` yields nothing and warns, and ``main`` says so and exits with status 2.

The data
--------
Laidig, Caruso, Cereatti, Seel (2021), *BROAD — A Benchmark for Robust Inertial Orientation Estimation*,
Data 6(7):72, CC BY 4.0.  One 9-axis IMU (≈ 285.7 Hz) and an optical reference ``q_ENU_marker``
(NaN where markers were lost); ``movement`` marks the samples that count.

The metric (Laidig et al. 2021, §3.3)
--------------------------------------
The error is expressed in the earth frame,

.. math::  q_\mathrm{err} = q_\mathrm{est} \otimes q_\mathrm{ref}^{*},

and split by a swing–twist decomposition about the vertical axis:

* total error  :math:`e = 2\operatorname{atan2}(\lVert \mathbf v_\mathrm{err}\rVert, |w_\mathrm{err}|)` — the angle of
  :math:`q_\mathrm{err}`;
* heading error :math:`e_h = 2\operatorname{atan2}(|z_\mathrm{err}|, |w_\mathrm{err}|)` — the twist about ``z``;
* inclination error :math:`e_i = 2\operatorname{atan2}(\sqrt{x^2+y^2}, \sqrt{w^2+z^2})` — the remaining swing
  (the tilt of the estimated vertical).

Each is reduced to an RMSE (degrees) over the ``movement`` samples where the reference is valid.

Alignment.  The reference and the estimate may differ by two constant rotations: the marker frame vs the
IMU frame (``q_marker_imu``) and the optical ENU frame vs the estimate's earth frame (a rotation about the
vertical, ``q_earth_opt``), so that :math:`q_\mathrm{ref,aligned} = q_{earth,opt} \otimes q_\mathrm{ref}
\otimes q_{marker,imu}`.  Both are fitted on *every* reference-valid sample of the trial (not only the
movement phase) by alternating least squares on the chordal cost :math:`\sum_k 1 - (q_{\mathrm{est},k} \cdot
q_{\mathrm{ref,aligned},k})^2`: with one rotation fixed, the other is the dominant eigenvector of a 4×4
(body) or 2×2 (heading, quaternions restricted to the span of ``w`` and ``z``) scatter matrix (Markley's
quaternion average).  Its per-sample cost :math:`\sin^2(e/2)` saturates, so short large errors barely pull
the fit.  Two starts (body first, heading first) are tried and the lower cost is kept.

What BROAD does, and what this module does by default (``align="broad"``).  The published files are
already aligned by the dataset's authors (the HDF5 ``info`` attribute says "synchronized and aligned
optical reference data": marker frame = IMU frame, optical ENU = magnetic ENU), and BROAD's own evaluation
compares the estimate with the stored reference directly.  So:

* **9D**: no alignment at all.  Fitting a heading offset per estimate would absorb a filter's constant
  heading error — exactly what the magnetically disturbed trials test (VQF offline, trial 27: 6.4° as
  published, 0.8° after a fitted heading offset);
* **6D**: heading is unobservable, so one constant heading offset per trial (the least-squares one above)
  is removed before scoring.

Held out (``--held-out``, on by default; ``--no-held-out`` skips it)
-------------------------------------------------------------------
Beside the all-trials table (one parameter set, the defaults), each project method's main parameters
are chosen on one half of the ten trials and scored on the other half, for both splits (``SPLITS``):
half A = trials 02 10 18 24 30, half B = 07 15 27 32 35 (undisturbed 02–18 / disturbed 24–35 split
3+2 and 2+3).  The grid (``GRIDS``, stated in the table) is small; the choice minimises the mean total
RMSE over the tuning half, per mode (keys that act only on the field, ``NINE_D_ONLY``, are not
varied in 6D).  ``chakamo``'s grid includes ``offline_mag_bias`` (on/off): the feature's design looked at
trials 32 and 35 (half B), so each tuning half must choose it for the held-out score to be evidence.  The table prints, per mode and split, the chosen values, the
tuned-half score and the held-out half's undisturbed / disturbed means, beside VQF offline and online
on the same held-out trials.

``align="full"`` fits both rotations (body misalignment and heading offset) in both modes — for
recordings whose reference is not pre-aligned; on BROAD it makes 9D scores optimistic.  Checks: VQF
offline scores 1.66° / 3.00° (9D, undisturbed / disturbed means) and 1.08° / 2.56° (6D); the ``ahrs``
Madgwick (β = 0.12 rad/s, as BROAD's run) lands near BROAD's published Madgwick table (``PUBLISHED_MADGWICK``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from benchmarks.baselines import COMPARISONS, MODES, EstimateFn, FloatArray, project_method
from estimators import quaternion as quat

DATA_ENV = "CHAKAMO_BROAD_DIR"
GROUPS = ("undisturbed", "disturbed")
ALIGNMENTS = ("broad", "full")

#: BROAD's own Madgwick run (their C code, β = 0.12), 9D RMSE in degrees: total, heading, inclination
#: (from the data folder's README, which quotes the publication's results).
PUBLISHED_MADGWICK: dict[str, tuple[float, float, float]] = {
    "02": (1.50, 1.26, 0.80), "07": (5.00, 4.33, 2.50), "10": (3.57, 1.71, 3.13),
    "15": (12.30, 11.41, 4.62), "18": (4.46, 2.87, 3.42), "24": (1.77, 1.24, 1.26),
    "27": (10.62, 10.50, 1.57), "30": (5.57, 1.81, 5.26), "32": (15.76, 14.96, 4.97),
    "35": (3.27, 1.14, 3.06),
}


# --------------------------------------------------------------------------------------------- data
@dataclass(frozen=True)
class Trial:
    """One BROAD trial; arrays as in ``../shared/DESIGN.md`` §3, ``quat_ref`` = ``q_ENU_marker`` (NaN rows: no reference)."""

    name: str
    group: str  # "undisturbed" | "disturbed"
    acc: FloatArray  # (N, 3) m/s²
    gyr: FloatArray  # (N, 3) rad/s
    mag: FloatArray  # (N, 3) µT
    quat_ref: FloatArray  # (N, 4)
    movement: NDArray[np.bool_]  # (N,) samples that count for the metric
    fs_hz: float
    description: str = ""

    @property
    def number(self) -> str:
        """The two-digit trial number, e.g. ``"02"``."""
        return self.name[:2]

    @property
    def n(self) -> int:
        return self.acc.shape[0]


def data_dir(dir: str | os.PathLike[str] | None = None) -> Path | None:
    """The BROAD folder: ``dir``, else ``$CHAKAMO_BROAD_DIR``, else ``../shared/data/broad`` beside the repo; ``None`` if absent."""
    if dir is not None:
        candidates = [Path(dir)]
    elif os.environ.get(DATA_ENV):
        candidates = [Path(os.environ[DATA_ENV])]
    else:
        repo = Path(__file__).resolve().parents[1]
        candidates = [repo.parent / "shared" / "data" / "broad", repo.parent.parent / "shared" / "data" / "broad"]
    for path in candidates:
        if path.is_dir() and any(path.glob("*.hdf5")):
            return path
    return None


def _group_of(name: str, info: dict[str, Any] | None) -> str:
    if info is not None and name in info.get("trials", {}):
        groups = info["trials"][name]["groups"]
        return "disturbed" if "disturbed" in groups else "undisturbed"
    return "disturbed" if "disturbed" in name.split("_")[1:2] else "undisturbed"


def load_trial(path: str | os.PathLike[str]) -> Trial:
    """Read one BROAD HDF5 file (its group comes from ``trials.json`` beside it, else from its name)."""
    import h5py  # optional dependency (the "bench" extra)

    path = Path(path)
    info_path = path.parent / "trials.json"
    info = json.loads(info_path.read_text()) if info_path.exists() else None
    with h5py.File(path, "r") as f:
        missing = {"imu_acc", "imu_gyr", "imu_mag", "opt_quat", "movement"} - set(f.keys())
        if missing:
            raise ValueError(f"{path} is not a BROAD trial: datasets {sorted(missing)} are missing")
        description = f.attrs.get("info", "")
        return Trial(
            name=path.stem,
            group=_group_of(path.stem, info),
            acc=np.ascontiguousarray(f["imu_acc"][:], dtype=np.float64),
            gyr=np.ascontiguousarray(f["imu_gyr"][:], dtype=np.float64),
            mag=np.ascontiguousarray(f["imu_mag"][:], dtype=np.float64),
            quat_ref=np.asarray(f["opt_quat"][:], dtype=np.float64),
            movement=np.asarray(f["movement"][:], dtype=bool).reshape(-1),
            fs_hz=float(f.attrs["sampling_rate"]),
            description=description.decode() if isinstance(description, bytes) else str(description),
        )


def trials(dir: str | os.PathLike[str] | None = None) -> Iterator[Trial]:
    """Yield every trial of the BROAD folder in name order; nothing (with a warning) when it is absent."""
    path = data_dir(dir)
    if path is None:
        warnings.warn(
            f"BROAD data not found (set {DATA_ENV} or place it in ../shared/data/broad): no trials", stacklevel=2
        )
        return
    for file in sorted(path.glob("*.hdf5")):
        yield load_trial(file)


_iter_trials = trials  # evaluate() has a parameter of that name


# ------------------------------------------------------------------------------------------- metric
@dataclass(frozen=True)
class Errors:
    """RMSE (degrees) of one estimate on one trial, and the alignment that was removed first."""

    total_deg: float
    heading_deg: float
    inclination_deg: float
    n_samples: int  # movement samples with a valid reference
    heading_offset_deg: float  # fitted earth-frame heading offset (0 when not fitted)
    body_misalignment_deg: float  # fitted IMU-vs-marker rotation angle (0 when not fitted)


def error_angles(q_est: ArrayLike, q_ref: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per-sample total, heading and inclination error (rad) of ``q_err = q_est ⊗ q_ref*`` (earth frame)."""
    e = quat.multiply(q_est, quat.conjugate(q_ref))
    e = e / np.linalg.norm(e, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(np.abs(e), -1, 0)
    total = 2.0 * np.arctan2(np.sqrt(x * x + y * y + z * z), w)
    heading = 2.0 * np.arctan2(z, w)
    inclination = 2.0 * np.arctan2(np.sqrt(x * x + y * y), np.sqrt(w * w + z * z))
    return total, heading, inclination


def _dominant(scatter: FloatArray) -> FloatArray:
    return np.linalg.eigh(scatter)[1][:, -1]


def _fit_heading(q_est: FloatArray, q_ref_body: FloatArray) -> FloatArray:
    """The rotation about z, ``h``, maximising Σ (q_est · h ⊗ q_ref_body)²."""
    c = quat.multiply(q_est, quat.conjugate(q_ref_body))[:, [0, 3]]
    v = _dominant(c.T @ c)
    return np.array([v[0], 0.0, 0.0, v[1]])


def _fit_body(q_est: FloatArray, q_ref_earth: FloatArray) -> FloatArray:
    """The constant ``b`` maximising Σ (q_est · q_ref_earth ⊗ b)²."""
    a = quat.multiply(quat.conjugate(q_ref_earth), q_est)
    return _dominant(a.T @ a)


def _cost(q_est: FloatArray, q_aligned: FloatArray) -> float:
    return float(np.sum(1.0 - np.sum(q_est * q_aligned, axis=-1) ** 2))


def fit_alignment(
    q_est: ArrayLike, q_ref: ArrayLike, *, heading: bool = True, body: bool = False, iterations: int = 30,
) -> tuple[FloatArray, FloatArray]:
    """Constant ``(q_earth_opt, q_marker_imu)`` with ``q_est ≈ q_earth_opt ⊗ q_ref ⊗ q_marker_imu`` (least squares).

    ``q_earth_opt`` is a rotation about the vertical (identity unless ``heading``), ``q_marker_imu`` any
    rotation (identity unless ``body``).  Rows with NaN in either input are ignored.
    """
    q_est = np.asarray(q_est, dtype=np.float64)
    q_ref = np.asarray(q_ref, dtype=np.float64)
    ok = np.isfinite(q_est).all(axis=1) & np.isfinite(q_ref).all(axis=1)
    q_est, q_ref = quat.normalize(q_est[ok]), quat.normalize(q_ref[ok])
    one = quat.identity()
    if q_est.shape[0] == 0 or not (heading or body):
        return one, one.copy()
    best: tuple[float, FloatArray, FloatArray] | None = None
    for heading_first in ((True, False) if heading and body else (heading,)):
        h, b = one, one.copy()
        cost = np.inf
        for it in range(iterations if heading and body else 1):  # a single rotation is fitted exactly at once
            if heading and (heading_first or it > 0):
                h = _fit_heading(q_est, quat.multiply(q_ref, b))
            if body:
                b = _fit_body(q_est, quat.multiply(h, q_ref))
            previous, cost = cost, _cost(q_est, quat.multiply(quat.multiply(h, q_ref), b))
            if previous - cost <= 1e-12 * max(cost, 1.0):
                break
        if best is None or cost < best[0]:
            best = (cost, h, b)
    assert best is not None
    return quat.positive_scalar(best[1]), quat.positive_scalar(best[2])


def broad_errors(
    q_est: ArrayLike,
    trial_or_ref: Trial | ArrayLike,
    movement: ArrayLike | None = None,
    *,
    mode: str = "9d",
    align: str = "broad",
) -> Errors:
    """Score ``q_est`` (``q_earth_sensor`` (N, 4), ENU) against a trial (or a reference and a movement mask).

    ``mode="6d"`` removes one constant heading offset; ``align="full"`` also fits the body misalignment
    and (in 9D too) the heading offset — see the module docstring.  NaN in ``q_est`` on a scored sample makes
    the RMSE NaN (a broken filter is not hidden).
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if align not in ALIGNMENTS:
        raise ValueError(f"align must be one of {ALIGNMENTS}, got {align!r}")
    if isinstance(trial_or_ref, Trial):
        q_ref, move = trial_or_ref.quat_ref, trial_or_ref.movement
    else:
        if movement is None:
            raise ValueError("give a Trial, or a reference (N, 4) and a movement mask (N,)")
        q_ref, move = np.asarray(trial_or_ref, dtype=np.float64), np.asarray(movement, dtype=bool)
    q_est = np.asarray(q_est, dtype=np.float64)
    if q_est.shape != q_ref.shape or q_ref.ndim != 2 or q_ref.shape[1] != 4 or move.shape != q_ref.shape[:1]:
        raise ValueError(
            f"shapes disagree: q_est {q_est.shape}, reference {q_ref.shape}, movement {move.shape} "
            "(expected (N, 4), (N, 4), (N,))"
        )
    valid = np.isfinite(q_ref).all(axis=1)
    fit_heading = mode == "6d" or align == "full"
    h, b = fit_alignment(q_est[valid], q_ref[valid], heading=fit_heading, body=align == "full")
    scored = valid & move
    if not scored.any():
        raise ValueError("no movement sample has a valid reference: nothing to score")
    q_aligned = quat.multiply(quat.multiply(h, q_ref[scored]), b)
    total, heading, inclination = error_angles(q_est[scored], q_aligned)

    def rmse_deg(e: FloatArray) -> float:
        return float(np.degrees(np.sqrt(np.mean(e * e))))

    return Errors(
        total_deg=rmse_deg(total),
        heading_deg=rmse_deg(heading),
        inclination_deg=rmse_deg(inclination),
        n_samples=int(scored.sum()),
        heading_offset_deg=float(np.degrees(2.0 * np.arctan2(h[3], h[0]))),
        body_misalignment_deg=float(np.degrees(quat.angle_between(quat.identity(), b))),
    )


# ---------------------------------------------------------------------------------------- evaluate
def evaluate(
    estimate_fn: EstimateFn,
    *,
    trials: Iterable[Trial] | None = None,
    mode: str = "9d",
    align: str = "broad",
    name: str = "",
) -> list[dict[str, Any]]:
    """Run ``estimate_fn(acc, gyr, mag_or_None, fs_hz) -> q_earth_sensor (N, 4)`` on every trial and score it.

    ``mode="6d"`` passes ``mag=None``.  One row per trial: ``method, mode, trial, group, total_deg,
    heading_deg, inclination_deg, n_samples, heading_offset_deg, body_misalignment_deg, runtime_s``.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    trial_list = list(_iter_trials() if trials is None else trials)
    rows = []
    for trial in trial_list:
        start = time.perf_counter()
        q = np.asarray(estimate_fn(trial.acc, trial.gyr, trial.mag if mode == "9d" else None, trial.fs_hz),
                       dtype=np.float64)
        runtime_s = time.perf_counter() - start
        errors = broad_errors(q, trial, mode=mode, align=align)
        rows.append({
            "method": name or getattr(estimate_fn, "__name__", "estimate"), "mode": mode, "trial": trial.name,
            "group": trial.group, **errors.__dict__, "runtime_s": runtime_s,
        })
    return rows


def group_means(rows: Sequence[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Mean RMSE per group over trials (BROAD averages per-trial RMSEs), plus ``"all"``."""
    out = {}
    for group in (*GROUPS, "all"):
        sel = [r for r in rows if group in ("all", r["group"])]
        if sel:
            out[group] = {k: float(np.mean([r[k] for r in sel])) for k in ("total_deg", "heading_deg", "inclination_deg")}
    return out


def method_table(names: Sequence[str] | None, with_ahrs: bool) -> dict[str, tuple[EstimateFn, tuple[str, ...]]]:
    """The project's methods (``estimators.orientation.METHODS``) and the comparison rows, by name."""
    from estimators.orientation import METHODS

    table: dict[str, tuple[EstimateFn, tuple[str, ...]]] = {m: (project_method(m), MODES) for m in METHODS}
    for key, (fn, modes, slow) in COMPARISONS.items():
        if with_ahrs or not slow:
            table[key] = (fn, modes)
    if names:
        unknown = [n for n in names if n not in table and n not in COMPARISONS]
        if unknown:
            raise SystemExit(f"unknown method(s) {', '.join(unknown)}; choose from {', '.join([*table, *COMPARISONS])}")
        table = {n: table.get(n) or COMPARISONS[n][:2] for n in names}
    return table


# ------------------------------------------------------------------------------------------ report
def _fmt(x: float) -> str:
    return f"{x:6.2f}" if np.isfinite(x) else "   nan"


def format_tables(rows: Sequence[dict[str, Any]], mode: str) -> str:
    """Summary (group means) and per-trial tables (total / heading / inclination) for one mode."""
    rows = [r for r in rows if r["mode"] == mode]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    trial_names = list(dict.fromkeys(r["trial"] for r in rows))
    published = mode == "9d" and all(t[:2] in PUBLISHED_MADGWICK for t in trial_names)
    width = max([len(m) for m in methods] + [len("BROAD madgwick (published)")])
    lines = [f"== BROAD {mode.upper()}: RMSE in degrees (total / heading / inclination) ==", ""]
    head = f"{'method':<{width}} | {'undisturbed T':>13} {'H':>6} {'I':>6} | {'disturbed T':>11} {'H':>6} {'I':>6} | {'all T':>6} | {'s':>6}"
    lines += [head, "-" * len(head)]

    def summary(label: str, by_group: dict[str, dict[str, float]], seconds: float | None) -> str:
        cells = []
        for g, w in (("undisturbed", 13), ("disturbed", 11)):
            m = by_group.get(g)
            cells.append(
                f"{_fmt(m['total_deg']):>{w}} {_fmt(m['heading_deg'])} {_fmt(m['inclination_deg'])}" if m
                else f"{'':>{w}} {'':>6} {'':>6}"
            )
        secs = f"{seconds:6.1f}" if seconds is not None else f"{'':>6}"
        return f"{label:<{width}} | {cells[0]} | {cells[1]} | {_fmt(by_group['all']['total_deg'])} | {secs}"

    for m in methods:
        sel = [r for r in rows if r["method"] == m]
        lines.append(summary(m, group_means(sel), sum(r["runtime_s"] for r in sel)))
    if published:
        pub = [{"group": "disturbed" if int(t[:2]) >= 22 else "undisturbed",
                **dict(zip(("total_deg", "heading_deg", "inclination_deg"), PUBLISHED_MADGWICK[t[:2]]))}
               for t in trial_names]
        lines.append(summary("BROAD madgwick (published)", group_means(pub), None))
    for key, label in (("total_deg", "total"), ("heading_deg", "heading"), ("inclination_deg", "inclination")):
        lines += ["", f"-- per trial, {label} RMSE (deg) --"]
        head = f"{'method':<{width}} | " + " ".join(f"{t[:2]:>6}" for t in trial_names)
        lines += [head, "-" * len(head)]
        for m in methods:
            by_trial = {r["trial"]: r[key] for r in rows if r["method"] == m}
            lines.append(f"{m:<{width}} | " + " ".join(_fmt(by_trial.get(t, np.nan)) for t in trial_names))
        if published:
            i = ("total_deg", "heading_deg", "inclination_deg").index(key)
            lines.append(f"{'BROAD madgwick (published)':<{width}} | "
                         + " ".join(_fmt(PUBLISHED_MADGWICK[t[:2]][i]) for t in trial_names))
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------- held out
_DEG = float(np.pi / 180.0)
#: two halves of the ten shared trials (undisturbed 02–18 / disturbed 24–35 split 3+2 and 2+3)
SPLITS: dict[str, tuple[str, ...]] = {"A": ("02", "10", "18", "24", "30"), "B": ("07", "15", "27", "32", "35")}
#: the main parameters of each method and the values tried (the defaults are among them)
GRIDS: dict[str, dict[str, tuple[Any, ...]]] = {
    # bias_sigma_motion_rad_s: 0.1-1.6 deg/s put 6D's choice on the lower edge; below 0.0125 the halves' scores are
    # flat, and these five points choose as the factor-2 grid 0.0125-1.6 does (chakamo.py (8b x))
    "chakamo": {"offline_tau_mag_s": (10.0, 20.0, 40.0),
                "bias_sigma_motion_rad_s": tuple(x * _DEG for x in (0.0125, 0.05, 0.2, 0.8, 1.6)),
                "offline_mag_bias": (False, True)},
    "guo": {"acc_noise_rad": (0.1, 0.2, 0.4), "mag_noise_rad": (0.075, 0.15, 0.3)},
    "madgwick": {"beta_rad_s": (0.02, 0.03, 0.05, 0.1)},
    "valenti_cf": {"tau_acc_s": (-0.01 / np.log1p(-0.01), 2.0, 5.0), "tau_mag_s": (5.0, 8.0, 10.0, 20.0)},
    "valenti_kf": {"acc_noise_m_s2_sqrt_hz": (0.02, 0.045, 0.1), "mag_noise_rel_sqrt_hz": (0.0034, 0.0067, 0.0134)},
}


#: grid keys that only act on the field: not varied in 6D (every value gives the same run)
NINE_D_ONLY = frozenset({"offline_mag_bias", "offline_tau_mag_s"})


def _grid(name: str, mode: str = "9d") -> list[dict[str, Any]]:
    keys = [k for k in GRIDS[name] if mode == "9d" or k not in NINE_D_ONLY]
    combos: list[dict[str, Any]] = [{}]
    for key in keys:
        combos = [{**c, key: v} for c in combos for v in GRIDS[name][key]]
    return combos


def _score_one(task: tuple[str, str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """One grid point on every trial (``_WORKER_TRIALS``), rows by trial number."""
    name, mode, params = task
    rows = evaluate(project_method(name, **params), trials=_WORKER_TRIALS, mode=mode, name=name)
    return {r["trial"][:2]: r for r in rows}


def held_out(names: Sequence[str], trial_list: Sequence[Trial], modes: Sequence[str],
             jobs: int = 1) -> list[dict[str, Any]]:
    """For each method, mode and split: the grid point best on the tuning half, scored on the other half
    (``jobs`` > 1: the grid points run in that many forked worker processes)."""
    by_number = {t.number: t for t in trial_list}
    if not all(n in by_number for half in SPLITS.values() for n in half):
        return []
    _WORKER_TRIALS[:] = trial_list
    tasks = [(name, mode, params) for name in names if name in GRIDS for mode in modes for params in _grid(name, mode)]
    if jobs > 1:
        from multiprocessing import get_context

        with get_context("fork").Pool(jobs) as pool:
            scored = pool.map(_score_one, tasks, chunksize=1)
    else:
        scored = [_score_one(t) for t in tasks]
    out = []
    for name in names:
        if name not in GRIDS:
            continue
        for mode in modes:
            # (params, rows over all ten trials)
            scores = [(t[2], rows) for t, rows in zip(tasks, scored, strict=True) if t[:2] == (name, mode)]
            for tune, test in (("A", "B"), ("B", "A")):
                def mean_total(rows: dict[str, dict[str, Any]], half: str) -> float:
                    return float(np.mean([rows[n]["total_deg"] for n in SPLITS[half]]))

                params, rows = min(scores, key=lambda pr: mean_total(pr[1], tune))
                out.append({"method": name, "mode": mode, "tuned_on": tune, "params": params,
                            "tuned_deg": mean_total(rows, tune),
                            **{g: group_means([rows[n] for n in SPLITS[test]]).get(g, {}).get("total_deg", np.nan)
                               for g in (*GROUPS, "all")}})
    for key in ("vqf_offline", "vqf_online"):
        fn = COMPARISONS[key][0]
        for mode in modes:
            rows = {r["trial"][:2]: r for r in evaluate(fn, trials=trial_list, mode=mode, name=key)}
            for tune, test in (("A", "B"), ("B", "A")):
                out.append({"method": key, "mode": mode, "tuned_on": tune, "params": {}, "tuned_deg": np.nan,
                            **{g: group_means([rows[n] for n in SPLITS[test]]).get(g, {}).get("total_deg", np.nan)
                               for g in (*GROUPS, "all")}})
    return out


def format_held_out(rows: Sequence[dict[str, Any]]) -> str:
    """One table per mode: chosen parameters, tuned-half score, held-out undisturbed / disturbed / all."""
    lines = []
    for mode in dict.fromkeys(r["mode"] for r in rows):
        lines += ["", f"== BROAD {mode.upper()} held out: total RMSE (deg); parameters chosen on one half, scored "
                      f"on the other (A = {' '.join(SPLITS['A'])}, B = {' '.join(SPLITS['B'])}) =="]
        head = (f"{'method':<12} | {'tuned on':>8} | {'tuned':>6} | {'held-out undist':>15} {'dist':>6} {'all':>6} | "
                "chosen (grid: benchmarks.broad.GRIDS)")
        lines += [head, "-" * len(head)]
        for r in (r for r in rows if r["mode"] == mode):
            chosen = ", ".join(f"{k}={v}" if isinstance(v, bool) else f"{k}={v:.4g}"
                               for k, v in r["params"].items()) or "(defaults, not tuned)"
            lines.append(f"{r['method']:<12} | {r['tuned_on'] + '->' + ('B' if r['tuned_on'] == 'A' else 'A'):>8} | "
                         f"{_fmt(r['tuned_deg'])} | {_fmt(r['undisturbed']):>15} {_fmt(r['disturbed'])} "
                         f"{_fmt(r['all'])} | {chosen}")
    return "\n".join(lines)


_WORKER_TRIALS: list[Trial] = []  # set before the worker pool forks, so trials are not pickled per task


def _run_one(task: tuple[str, str, str]) -> tuple[list[dict[str, Any]], str | None]:
    name, mode, align = task
    fn = COMPARISONS[name][0] if name in COMPARISONS else project_method(name)
    try:
        return evaluate(fn, trials=_WORKER_TRIALS, mode=mode, align=align, name=name), None
    except (ImportError, NotImplementedError) as exc:  # a method whose module is not written yet
        return [], f"skipped {name} ({mode}): {type(exc).__name__}: {exc}"
    except Exception as exc:  # noqa: BLE001 - one broken method must not stop the others' table
        return [], f"FAILED {name} ({mode}): {type(exc).__name__}: {exc}"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.broad", description=__doc__.split("\n")[0])
    parser.add_argument("--mode", choices=(*MODES, "both"), default="both")
    parser.add_argument("--methods", nargs="+", metavar="NAME", help="methods to run (default: all)")
    parser.add_argument("--no-ahrs", action="store_true", help="skip the slow pure-Python ahrs comparison rows")
    parser.add_argument("--align", choices=ALIGNMENTS, default="broad", help="alignment (module docstring)")
    parser.add_argument("--trials", nargs="+", metavar="NN", help="only these trial numbers (e.g. 02 27)")
    parser.add_argument("--data", help=f"BROAD folder (default: ${DATA_ENV} or ../shared/data/broad)")
    parser.add_argument("--jobs", type=int, default=1,
                        help="worker processes (one (method, mode) per task; held out: one grid point per task)")
    parser.add_argument("--json", metavar="OUT", help="also write every row to this JSON file")
    parser.add_argument("--no-held-out", action="store_true", help="skip the held-out parameter choice (docstring)")
    args = parser.parse_args(argv)

    folder = data_dir(args.data)
    if folder is None:
        print(f"BROAD data not found: set {DATA_ENV}, pass --data, or place it in ../shared/data/broad", file=sys.stderr)
        return 2
    trial_list = [t for t in trials(folder) if not args.trials or t.number in args.trials]
    if not trial_list:
        print(f"no trial numbered {' '.join(args.trials)} in {folder}", file=sys.stderr)
        return 2
    _WORKER_TRIALS[:] = trial_list
    modes = MODES if args.mode == "both" else (args.mode,)
    table = method_table(args.methods, with_ahrs=not args.no_ahrs)
    tasks = [(name, mode, args.align) for name, (_, ms) in table.items() for mode in modes if mode in ms]
    print(f"BROAD: {len(trial_list)} trials from {folder}; {len(tasks)} (method, mode) runs; align={args.align}",
          flush=True)
    start = time.perf_counter()
    if args.jobs > 1:
        from multiprocessing import get_context

        slow_first = sorted(tasks, key=lambda t: not COMPARISONS.get(t[0], (None, None, False))[2])
        with get_context("fork").Pool(args.jobs) as pool:
            done = dict(zip(slow_first, pool.map(_run_one, slow_first, chunksize=1)))
        results = [done[t] for t in tasks]
    else:
        results = [_run_one(t) for t in tasks]
    rows = [r for rs, _ in results for r in rs]
    notes = [n for _, n in results if n]
    for mode in modes:
        if any(r["mode"] == mode for r in rows):
            print("\n" + format_tables(rows, mode))
    held = []
    if not args.no_held_out:
        from estimators.orientation import METHODS

        held = held_out([n for n in table if n in METHODS], trial_list, modes, jobs=args.jobs)
        if held:
            print(format_held_out(held))
        else:
            print("\nheld out: skipped (needs all ten shared trials; see --trials)")
    for note in notes:
        print(note)
    print(f"\ntotal wall time {time.perf_counter() - start:.0f} s")
    if args.json:
        Path(args.json).write_text(json.dumps({"align": args.align, "rows": rows, "notes": notes, "held_out": held},
                                              indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
