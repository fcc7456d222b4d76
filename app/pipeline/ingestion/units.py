r"""Units: parse a declared unit, convert to project units once, and refuse implausible magnitudes.

Conversions (to m/s², rad/s, µT, s)::

    acc   g ×9.80665   mg ×9.80665e-3   m/s² ×1
    gyr   deg/s ×π/180   rad/s ×1   mdeg/s ×π/180e3
    mag   T ×1e6   mT ×1e3   µT ×1   nT ×1e-3   G (gauss) ×100   mG ×0.1
    time  s ×1   ms ×1e-3   µs ×1e-6

Plausibility (a file whose header declares one unit but whose numbers are in another):

* acc: the median norm over the recording is gravity-dominated, so it must be 4–25 m/s²;
* mag: the median norm must be 5–1000 µT (earth 25–65 µT plus hard iron);
* gyr: at rest a gyroscope reads noise in any unit, so magnitude alone cannot tell deg/s from
  rad/s.  Instead the rotation of the gravity direction seen by the accelerometer over 0.5 s windows,
  :math:`\theta_{acc}=\angle(\bar u(t), \bar u(t+0.5))`, is compared with the gyroscope's rotation
  angle bound :math:`\theta_{gyr}=\int|\omega|dt \ge \theta_{acc}`.  With the right unit the median ratio
  :math:`\theta_{acc}/\theta_{gyr}` is ≤ ~1; rad/s read as deg/s makes it ≈ 57 (refused above 5), deg/s
  read as rad/s ≈ 0.017 (refused below 0.05).  Needs ≥ 3 windows with θ_acc > 15°, else not checked.
  Independently, |ω| beyond 40 rad/s (above any IMU range) is refused.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from app.pipeline.ingestion.model import FloatArray, IngestionError, Stream, rows_all
from estimators.physics import STANDARD_GRAVITY_M_S2 as G_M_S2

ACC_UNITS = {"g": G_M_S2, "mg": G_M_S2 * 1e-3, "m/s2": 1.0}
GYR_UNITS = {"deg/s": math.pi / 180.0, "mdeg/s": math.pi / 180e3, "rad/s": 1.0}
MAG_UNITS = {"t": 1e6, "mt": 1e3, "ut": 1.0, "nt": 1e-3, "gauss": 100.0, "mgauss": 0.1}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
UNITS = {"acc": ACC_UNITS, "gyr": GYR_UNITS, "mag": MAG_UNITS, "time": TIME_UNITS}
_PRETTY = {"t": "T", "mt": "mT", "ut": "µT", "nt": "nT", "gauss": "G", "mgauss": "mG"}

_ALIASES = {
    "m/s^2": "m/s2", "ms2": "m/s2", "m/s/s": "m/s2", "mps2": "m/s2", "m_s2": "m/s2",
    "dps": "deg/s", "°/s": "deg/s", "degs": "deg/s", "deg_s": "deg/s", "degree/s": "deg/s", "degrees/s": "deg/s",
    "rad_s": "rad/s", "rads": "rad/s", "mdps": "mdeg/s",
    "tesla": "t", "microtesla": "ut", "millitesla": "mt", "nanotesla": "nt", "g(gauss)": "gauss",
    "sec": "s", "seconds": "s", "msec": "ms",
}


#: spellings of a normalised magnetometer unit (Xsens "a.u."): the field divided by its local strength, norm ≈ 1
NORMALISED = ("normalised", "normalized", "a.u.", "au", "arb", "norm")
_NORMALISED = re.compile(r"^(?:normali[sz]ed|a\.u\.|au|arb|norm)(?:[,;:@x*]?(?P<field>\d+(?:\.\d+)?)"
                         r"(?P<unit>ut|nt|mt|t|gauss|g|mg))?$")


def normalised_field(unit: str) -> tuple[bool, float | None]:
    """``(is_normalised, field_ut)`` of a magnetometer unit: ``"normalised"`` → ``(True, None)``,
    ``"normalised 48.5 uT"`` → ``(True, 48.5)``, ``"uT"`` → ``(False, None)``."""
    m = _NORMALISED.match(normalise_unit(unit))
    if m is None:
        return False, None
    if m.group("field") is None:
        return True, None
    return True, float(m.group("field")) * UNITS["mag"][_key("mag", m.group("unit"))]


def normalise_unit(text: str) -> str:
    """Lower-case, strip spaces, µ/μ → u, ² → 2, aliases → one spelling (``"m/s²"`` → ``"m/s2"``)."""
    u = text.strip().lower().replace(" ", "").replace("µ", "u").replace("μ", "u").replace("²", "2")
    return _ALIASES.get(u, u)


def _key(kind: str, unit: str) -> str:
    """``unit``'s spelling in ``UNITS[kind]``: for the magnetometer ``g``/``mg`` mean gauss/milligauss (the
    accelerometer's g is never a field unit)."""
    u = normalise_unit(unit)
    return {"g": "gauss", "mg": "mgauss"}.get(u, u) if kind == "mag" else u


def unit_factor(kind: str, unit: str) -> float | None:
    """Factor taking ``unit`` to the project unit of ``kind`` (acc/gyr/mag/time), ``None`` if unknown.

    A normalised magnetometer unit (:func:`normalised_field`) gives 1.0: its values stay normalised."""
    if kind == "mag" and normalised_field(unit)[0]:
        return 1.0
    return UNITS[kind].get(_key(kind, unit))


def pretty(kind: str, unit: str) -> str:
    """``unit`` as printed to a user (magnetometer units in their usual case: µT, G...)."""
    return _PRETTY.get(_key(kind, unit), unit) if kind == "mag" else unit


def _median_norm(values: FloatArray) -> float:
    n = np.linalg.norm(values, axis=1)
    n = n[np.isfinite(n)]
    return float(np.median(n)) if n.size else float("nan")


def _guess(kind: str, declared: str, norm_si: float, lo: float, hi: float) -> str:
    """The unit that would make ``norm_si`` fall in [lo, hi] (advice), ``""`` if none does."""
    raw = norm_si / unit_factor(kind, declared)
    for u, f in UNITS[kind].items():
        if lo <= raw * f <= hi and u != _key(kind, declared):
            return pretty(kind, u)
    return ""


#: kind → (plausible median norm lo, hi; range a correct unit would give, for the hint; what, SI unit, reference).
#: A magnetometer's raw norm is the earth's field plus the sensor's hard iron: held still (a posture) in one
#: orientation it can read a few µT where the offset nearly cancels the field (simulated MetaMotion errors: 4.1 and
#: 4.3 µT in 2 of 200 robustness sessions, refused at a 5 µT floor), so the floor is 1 µT — a unit mistake is a
#: factor of 100 or more (gauss read as µT: 0.25–0.65).
_PLAUSIBLE = {
    "acc": (4.0, 25.0, 8.0, 12.0, "accelerometer's typical magnitude", "m/s²", "gravity is 9.81 m/s²"),
    "mag": (1.0, 1000.0, 15.0, 200.0, "magnetometer's typical field", "µT", "the earth's field is 25–65 µT"),
}


def check_magnitude(kind: str, values_si: FloatArray, declared: str, file: Path) -> None:
    """Refuse acc/mag whose median norm is implausible for the declared unit (see module docstring)."""
    if kind == "mag" and normalised_field(declared)[0]:
        m = _median_norm(values_si)
        if not 0.3 <= m <= 3.0:
            raise IngestionError("unit.implausible_normalised", file=file, value=f"{m:.4g}")
        return
    if kind in _PLAUSIBLE:
        lo, hi, guess_lo, guess_hi, what, si, reference = _PLAUSIBLE[kind]
        m = _median_norm(values_si)
        if not lo <= m <= hi:
            guess = _guess(kind, declared, m, guess_lo, guess_hi)
            raise IngestionError("unit.implausible_acc" if kind == "acc" else "unit.implausible_mag", file=file,
                                 value=f"{m:.4g}", declared=pretty(kind, declared),
                                 hint=[{"code": "hint.looks_like", "params": {"unit": guess, "declared":
                                        pretty(kind, declared)}}] if guess else [])
    elif kind == "gyr":
        n = np.linalg.norm(values_si, axis=1)
        n = n[np.isfinite(n)]
        if n.size and float(np.max(n)) > 40.0:
            looks = normalise_unit(declared) == "rad/s" and np.max(n) * math.pi / 180.0 <= 40.0
            raise IngestionError("unit.gyr_beyond_range", file=file, value=f"{np.max(n):.4g}", declared=declared,
                                 hint=[{"code": "hint.looks_like", "params": {"unit": "deg/s",
                                                                              "declared": declared}}] if looks else [])


def _smooth(x: FloatArray, n: int) -> FloatArray:
    if n <= 1:
        return x
    kernel = np.ones(n) / n
    return np.stack([np.convolve(x[:, i], kernel, mode="same") for i in range(3)], axis=1)


def gyro_scale_ratio(acc: Stream, gyr: Stream, window_s: float = 0.5,
                     min_angle_rad: float = math.radians(15.0)) -> float | None:
    """Median θ_acc/θ_gyr over windows where gravity turned > ``min_angle_rad`` (module docstring).

    ``None`` when there is too little motion (fewer than 3 such windows) to judge.
    """
    ok_g = rows_all(np.isfinite(gyr.values))
    ok_a = rows_all(np.isfinite(acc.values))
    if ok_g.sum() < 10 or ok_a.sum() < 10:
        return None
    t = gyr.t_s[ok_g]
    w = gyr.values[ok_g]
    a = np.stack([np.interp(t, acc.t_s[ok_a], acc.values[ok_a, i]) for i in range(3)], axis=1)
    dt = float(np.median(np.diff(t)))
    u = _smooth(a, max(1, int(round(0.1 / dt))))
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    step = max(1, int(round(window_s / dt)))
    angle_g = np.concatenate([[0.0], np.cumsum(np.linalg.norm(w[1:], axis=1) * np.diff(t))])
    i0 = np.arange(0, len(t) - step, max(1, step // 2))
    i1 = i0 + step
    th_a = np.arccos(np.clip(np.sum(u[i0] * u[i1], axis=1), -1.0, 1.0))
    th_g = angle_g[i1] - angle_g[i0]
    sel = th_a > min_angle_rad
    if sel.sum() < 3:
        return None
    return float(np.median(th_a[sel] / np.maximum(th_g[sel], 1e-9)))


def check_gyro_unit(acc: Stream, gyr: Stream) -> None:
    """Refuse a gyroscope whose declared unit contradicts the accelerometer's rotation (module docstring)."""
    r = gyro_scale_ratio(acc, gyr)
    if r is None:
        return
    if r > 5.0:
        raise IngestionError("unit.gyr_looks_rad", file=gyr.file, ratio=f"{r:.0f}", declared=gyr.declared_unit)
    if r < 0.05:
        raise IngestionError("unit.gyr_looks_deg", file=gyr.file, ratio=f"{1 / r:.0f}", declared=gyr.declared_unit)
