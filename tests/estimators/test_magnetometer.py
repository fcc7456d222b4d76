"""Tests of estimators.magnetometer on synthetic figure-eight recordings made here.

Ground truth: m_raw = A · R_sensor_earth · h_earth + b + noise (module docstring eq. 1), with random
rotations covering the sphere, |h_earth| = 45 µT, b = (12, −30, 8) µT, A with ±10 % scales and small
cross terms, noise 0.3 µT per axis.  The fit can only see V = (A Aᵀ)^½ up to scale, so the expected
soft iron is W = det(V)^⅓ V⁻¹ and the expected field strength F det(V)^⅓.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from estimators import quaternion as quat
from estimators.magnetometer import MagCalibration, fit_ellipsoid, gate_norm

FIELD_UT = 45.0
OFFSET_UT = np.array([12.0, -30.0, 8.0])
A_SYM = np.array([[1.08, 0.03, -0.02], [0.03, 0.92, 0.04], [-0.02, 0.04, 1.05]])
NOISE_UT = 0.3


def true_field_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Earth field [0, B_h, −B_v] seen by a sensor in n uniformly random orientations, µT."""
    q_earth_sensor = quat.normalize(rng.normal(size=(n, 4)))
    h_earth = np.array([0.0, 20.0, -40.0])
    return quat.rotate(quat.conjugate(q_earth_sensor), h_earth * FIELD_UT / np.linalg.norm(h_earth))


def distort(m_true: np.ndarray, rng: np.random.Generator, a: np.ndarray = A_SYM, offset=OFFSET_UT,
            noise_ut: float = NOISE_UT) -> np.ndarray:
    return m_true @ a.T + offset + noise_ut * rng.normal(size=m_true.shape)


def expected_soft_iron(a: np.ndarray) -> tuple[np.ndarray, float]:
    """(W, scale): W = det(V)^⅓ V⁻¹ with V = (A Aᵀ)^½; the fitted field is FIELD_UT · scale."""
    evals, evecs = np.linalg.eigh(a @ a.T)
    v = (evecs * np.sqrt(evals)) @ evecs.T
    scale = np.linalg.det(v) ** (1.0 / 3.0)
    return scale * np.linalg.inv(v), scale


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def recording() -> np.ndarray:
    rng = np.random.default_rng(4)
    return distort(true_field_directions(rng, 1200), rng)


# --- accuracy ------------------------------------------------------------------------------------


def test_recovers_hard_and_soft_iron(recording):
    cal = fit_ellipsoid(recording)
    w_true, scale = expected_soft_iron(A_SYM)
    assert np.max(np.abs(cal.offset_ut - OFFSET_UT)) < 0.5
    assert rel_err(cal.soft_iron, w_true) < 0.02
    assert np.linalg.det(cal.soft_iron) == pytest.approx(1.0, abs=1e-9)
    assert np.allclose(cal.soft_iron, cal.soft_iron.T)
    assert cal.field_ut == pytest.approx(FIELD_UT * scale, rel=0.01)
    q = cal.quality
    assert q.reliable and q.warnings == ()
    assert q.coverage_fraction == 1.0 and q.coverage_cells == 20 and q.direction_spread > 0.8
    assert q.residual_rms_ut == pytest.approx(NOISE_UT, rel=0.25)
    assert q.residual_pct == pytest.approx(100 * q.residual_rms_ut / q.field_ut)
    assert q.offset_sd_ut < 0.1 and q.n_samples == 1200 and q.n_dropped_nan == 0 and q.n_outliers == 0


def test_non_symmetric_soft_iron_is_recovered_up_to_the_unobservable_rotation():
    rng = np.random.default_rng(5)
    rot = quat.to_matrix(quat.from_axis_angle([1.0, 2.0, -1.0], 0.08))
    a = A_SYM @ rot  # A = V U with U a 4.6° rotation: only V is observable
    cal = fit_ellipsoid(distort(true_field_directions(rng, 1200), rng, a=a))
    w_true, _ = expected_soft_iron(a)
    assert np.max(np.abs(cal.offset_ut - OFFSET_UT)) < 0.5
    assert rel_err(cal.soft_iron, w_true) < 0.02


def test_apply_gives_constant_norm(recording):
    rng = np.random.default_rng(6)
    clean = distort(true_field_directions(rng, 300), rng, noise_ut=0.0)
    cal = fit_ellipsoid(recording)
    norms_noisy = np.linalg.norm(cal.apply(recording), axis=1)
    norms_clean = np.linalg.norm(cal.apply(clean), axis=1)
    assert np.std(norms_noisy) < 0.4
    assert np.max(np.abs(norms_clean - cal.field_ut)) < 0.005 * cal.field_ut
    assert cal.apply(clean[0]).shape == (3,)
    with_gap = clean[:5].copy()
    with_gap[2] = np.nan
    out = cal.apply(with_gap)
    assert np.isnan(out[2]).all() and np.isfinite(np.delete(out, 2, axis=0)).all()


def test_noise_free_fit_is_exact():
    rng = np.random.default_rng(7)
    cal = fit_ellipsoid(distort(true_field_directions(rng, 400), rng, noise_ut=0.0))
    w_true, scale = expected_soft_iron(A_SYM)
    assert np.allclose(cal.offset_ut, OFFSET_UT, atol=1e-6)
    assert np.allclose(cal.soft_iron, w_true, atol=1e-8)
    assert cal.field_ut == pytest.approx(FIELD_UT * scale, rel=1e-9)


def test_sphere_model_fits_hard_iron_only():
    rng = np.random.default_rng(8)
    x = distort(true_field_directions(rng, 800), rng, a=np.eye(3))
    cal = fit_ellipsoid(x, model="sphere")
    assert cal.model == "sphere"
    assert np.array_equal(cal.soft_iron, np.eye(3))
    assert np.max(np.abs(cal.offset_ut - OFFSET_UT)) < 0.3
    assert cal.field_ut == pytest.approx(FIELD_UT, abs=0.2)
    # soft iron left uncorrected shows up as a residual warning
    with_soft_iron = distort(true_field_directions(rng, 800), rng)
    assert "MAG_RESIDUAL_HIGH" in fit_ellipsoid(with_soft_iron, model="sphere").quality.codes


def test_magnetic_disturbances_are_rejected():
    rng = np.random.default_rng(9)
    m = true_field_directions(rng, 1200)
    spikes = rng.choice(1200, size=24, replace=False)
    m[spikes] *= rng.choice([0.7, 1.3], size=(24, 1))  # a magnet passing by: ±13 µT on the norm
    cal = fit_ellipsoid(distort(m, rng))
    assert 24 <= cal.quality.n_outliers <= 30
    assert np.max(np.abs(cal.offset_ut - OFFSET_UT)) < 0.5
    assert cal.quality.reliable  # 2 % disturbed: below the MAG_DISTURBED threshold


# --- warnings and degenerate recordings ----------------------------------------------------------


def test_half_sphere_recording_warns_coverage():
    rng = np.random.default_rng(10)
    m = true_field_directions(rng, 2400)
    m = m[m[:, 2] > 0.0]  # never upside down
    q = fit_ellipsoid(distort(m, rng)).quality
    assert "MAG_COVERAGE_LOW" in q.codes and not q.reliable
    low = next(w for w in q.warnings if w.code == "MAG_COVERAGE_LOW")
    assert dict(low.params) == {"cells": q.coverage_cells, "spread": q.direction_spread}
    assert q.coverage_fraction <= 0.6 and q.direction_spread < 0.3


def poor_cap(rng: np.random.Generator, cap_deg: float, n: int = 600) -> np.ndarray:
    """Field directions within cap_deg of one direction: a figure-eight that never turned far."""
    m = true_field_directions(rng, 20 * n)
    return m[m @ np.array([0.0, 0.6, -0.8]) / FIELD_UT > np.cos(np.radians(cap_deg))][:n]


def test_thesis_like_poor_coverage_is_flagged_not_silent():
    rng = np.random.default_rng(11)
    cal = fit_ellipsoid(distort(poor_cap(rng, 75.0), rng))  # well short of a hemisphere
    assert "MAG_COVERAGE_LOW" in cal.quality.codes and not cal.quality.reliable
    assert cal.quality.coverage_cells <= 12
    small = distort(poor_cap(rng, 50.0), rng)
    with pytest.raises(ValueError, match="too few directions.*model='sphere'"):
        fit_ellipsoid(small)  # 9 parameters are not identifiable on a 50° cap
    hard_only = fit_ellipsoid(small, model="sphere")
    assert "MAG_COVERAGE_LOW" in hard_only.quality.codes
    with pytest.raises(ValueError, match="too few directions"):
        fit_ellipsoid(distort(poor_cap(rng, 25.0), rng, a=np.eye(3)), model="sphere")


@pytest.mark.parametrize("wobble_deg", [10.0, 30.0])
def test_nearly_planar_recording_is_refused_or_flagged(wobble_deg):
    rng = np.random.default_rng(12)
    angle = rng.uniform(0, 2 * np.pi, 800)
    wobble = rng.normal(scale=np.radians(wobble_deg), size=800)  # turned about z with a wobble
    q = quat.multiply(quat.from_axis_angle([0, 0, 1], angle), quat.from_axis_angle([1, 0, 0], wobble))
    x = distort(quat.rotate(quat.conjugate(q), np.array([0.0, 20.0, -40.0])), rng)
    if wobble_deg < 20.0:
        with pytest.raises(ValueError, match="too few directions"):
            fit_ellipsoid(x)
    else:
        assert "MAG_COVERAGE_LOW" in fit_ellipsoid(x).quality.codes


def test_planar_and_static_recordings_raise():
    rng = np.random.default_rng(13)
    q = quat.from_axis_angle([0, 0, 1], rng.uniform(0, 2 * np.pi, 500))
    planar = distort(quat.rotate(quat.conjugate(q), np.array([0.0, 20.0, -40.0])), rng)
    with pytest.raises(ValueError, match="plane"):
        fit_ellipsoid(planar)
    static = distort(np.tile([0.0, 20.0, -40.0], (500, 1)), rng)
    with pytest.raises(ValueError, match="hardly turned"):
        fit_ellipsoid(static)


def test_non_ellipsoid_data_raise():
    rng = np.random.default_rng(14)
    t, z = rng.uniform(0, 2 * np.pi, 600), rng.uniform(-30, 30, 600)
    r = np.sqrt(30.0**2 + z**2)  # one-sheet hyperboloid x² + y² − z² = 30²
    with pytest.raises(ValueError, match="ellipsoid"):
        fit_ellipsoid(np.column_stack([r * np.cos(t), r * np.sin(t), z]))


def test_field_strength_warnings():
    rng = np.random.default_rng(15)
    weak = distort(true_field_directions(rng, 800) * 18.4 / FIELD_UT, rng, noise_ut=0.1)
    assert "MAG_FIELD_IMPLAUSIBLE" in fit_ellipsoid(weak).quality.codes
    cal = fit_ellipsoid(distort(true_field_directions(rng, 800), rng), expected_field_ut=22.6)
    assert cal.quality.codes == ("MAG_FIELD_MISMATCH",)
    assert dict(cal.quality.warnings[0].params) == {"field_ut": cal.field_ut, "expected_ut": 22.6}
    implausible = fit_ellipsoid(weak).quality.warnings
    (p,) = [w.params for w in implausible if w.code == "MAG_FIELD_IMPLAUSIBLE"]
    assert (p["lo_ut"], p["hi_ut"]) == (20.0, 70.0) and p["field_ut"] == pytest.approx(18.4, abs=0.3)
    assert fit_ellipsoid(weak * 1.0, expected_field_ut=18.5).quality.codes == ("MAG_FIELD_IMPLAUSIBLE",)


def test_noisy_and_short_recordings_warn():
    rng = np.random.default_rng(16)
    noisy = fit_ellipsoid(distort(true_field_directions(rng, 1200), rng, noise_ut=2.5))
    assert "MAG_RESIDUAL_HIGH" in noisy.quality.codes
    short = fit_ellipsoid(distort(true_field_directions(rng, 120), rng))
    assert "MAG_FEW_SAMPLES" in short.quality.codes
    q = noisy.quality
    residual = next(w for w in q.warnings if w.code == "MAG_RESIDUAL_HIGH")
    assert dict(residual.params) == {"residual_ut": q.residual_rms_ut, "residual_pct": q.residual_pct}
    assert f"{q.residual_rms_ut:.2f} µT RMS" in residual.message
    few = next(w for w in short.quality.warnings if w.code == "MAG_FEW_SAMPLES")
    assert dict(few.params) == {"n_samples": short.quality.n_samples} and type(few.params["n_samples"]) is int


# --- bad input -----------------------------------------------------------------------------------


def test_nan_rows_are_dropped_and_counted(recording):
    x = recording.copy()
    x[[3, 50, 51]] = np.nan
    x[7, 1] = np.nan
    cal = fit_ellipsoid(x)
    assert cal.quality.n_dropped_nan == 4 and cal.quality.n_samples == 1196


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.zeros((100, 2)), "shape"),
        (np.zeros(300), "shape"),
        (np.zeros((10, 10, 3)), "shape"),
        ("abc", "numeric"),
        (np.full((40, 3), 30.0), "finite samples"),
    ],
)
def test_bad_inputs_raise(bad, match):
    with pytest.raises(ValueError, match=match):
        fit_ellipsoid(bad)


def test_infinite_values_and_too_few_finite_rows_raise(recording):
    x = recording[:100].copy()
    x[17, 2] = np.inf
    with pytest.raises(ValueError, match="infinite value at sample 17"):
        fit_ellipsoid(x)
    y = recording[:100].copy()
    y[:60] = np.nan
    with pytest.raises(ValueError, match="40 finite samples .60 NaN rows dropped"):
        fit_ellipsoid(y)


def test_bad_options_raise(recording):
    with pytest.raises(ValueError, match="model"):
        fit_ellipsoid(recording, model="cube")
    with pytest.raises(ValueError, match="expected_field_ut"):
        fit_ellipsoid(recording, expected_field_ut=-3.0)
    with pytest.raises(ValueError, match="min_samples"):
        fit_ellipsoid(recording, min_samples=3)


def test_result_is_immutable_and_serialisable(recording):
    cal = fit_ellipsoid(recording)
    assert isinstance(cal, MagCalibration)
    with pytest.raises(ValueError):
        cal.offset_ut[0] = 0.0
    d = json.loads(json.dumps(cal.to_dict()))
    assert d["quality"]["reliable"] is True and d["quality"]["warnings"] == []
    assert np.allclose(d["offset_ut"], cal.offset_ut) and d["field_ut"] == cal.field_ut
    assert cal.residual_rms_ut == cal.quality.residual_rms_ut and cal.coverage_fraction == 1.0


# --- norm gating (seed 004 §7.3) -----------------------------------------------------------------


def test_gate_norm_replaces_outliers_by_last_good_sample():
    rng = np.random.default_rng(17)
    directions = rng.normal(size=(10, 3))
    x = 22.6 * directions / np.linalg.norm(directions, axis=1)[:, None]
    x[0] *= 1.1  # bad before any good sample → NaN
    x[4] *= 1.05  # +1.1 µT
    x[5] *= 0.95  # −1.1 µT, follows another bad one
    x[7] = np.nan  # missing: stays missing, not "replaced"
    x[8] *= 1.03  # +0.7 µT, after a missing row
    gated, replaced = gate_norm(x, 0.5, reference_ut=22.6)
    assert replaced.tolist() == [True, False, False, False, True, True, False, False, True, False]
    assert np.isnan(gated[0]).all() and np.isnan(gated[7]).all()
    assert np.array_equal(gated[4], x[3]) and np.array_equal(gated[5], x[3]) and np.array_equal(gated[8], x[6])
    keep = ~replaced & ~np.isnan(x).any(axis=1)
    assert np.array_equal(gated[keep], x[keep])


def test_gate_norm_default_reference_is_the_mean_norm():
    x = np.array([[20.0, 0, 0], [0, 21.0, 0], [0, 0, 22.0], [23.0, 0, 0], [0, 24.0, 0]])  # mean 22
    gated, replaced = gate_norm(x, tolerance_ut=1.5)
    assert replaced.tolist() == [True, False, False, False, True]
    assert np.isnan(gated[0]).all() and np.array_equal(gated[4], x[3])


def test_gate_norm_bad_input():
    with pytest.raises(ValueError, match="tolerance_ut"):
        gate_norm(np.ones((5, 3)), 0.0)
    with pytest.raises(ValueError, match="reference_ut"):
        gate_norm(np.ones((5, 3)), 0.5, reference_ut=np.nan)
    with pytest.raises(ValueError, match="no finite sample"):
        gate_norm(np.full((5, 3), np.nan))
    with pytest.raises(ValueError, match="shape"):
        gate_norm(np.ones((5, 4)))


# --- properties ----------------------------------------------------------------------------------


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_fit_is_invariant_to_sample_order(seed):
    rng = np.random.default_rng(seed)
    x = distort(true_field_directions(rng, 300), rng)
    a, b = fit_ellipsoid(x), fit_ellipsoid(x[rng.permutation(300)])
    assert np.allclose(a.offset_ut, b.offset_ut, atol=1e-6)
    assert np.allclose(a.soft_iron, b.soft_iron, atol=1e-8)
    assert a.quality.codes == b.quality.codes


@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    offset=st.lists(st.floats(-150.0, 150.0), min_size=3, max_size=3),
    scales=st.lists(st.floats(0.9, 1.1), min_size=3, max_size=3),
    cross=st.lists(st.floats(-0.05, 0.05), min_size=3, max_size=3),
)
def test_recovery_and_recalibration_is_identity(seed, offset, scales, cross):
    rng = np.random.default_rng(seed)
    a = np.diag(scales) + np.array([[0, cross[0], cross[1]], [cross[0], 0, cross[2]], [cross[1], cross[2], 0]])
    x = distort(true_field_directions(rng, 300), rng, a=a, offset=np.array(offset))
    cal = fit_ellipsoid(x)
    w_true, _ = expected_soft_iron(a)
    assert np.max(np.abs(cal.offset_ut - offset)) < 0.5
    assert rel_err(cal.soft_iron, w_true) < 0.02
    again = fit_ellipsoid(cal.apply(x))  # calibrating a calibrated set changes nothing
    assert np.max(np.abs(again.offset_ut)) < 1e-6
    assert np.allclose(again.soft_iron, np.eye(3), atol=1e-6)
    assert again.field_ut == pytest.approx(cal.field_ut, rel=1e-9)


# --- real data (skips when ../shared is absent) --------------------------------------------------

METABASE = Path(__file__).resolve().parents[3] / "shared" / "data" / "metabase"


@pytest.mark.skipif(not METABASE.is_dir(), reason="../shared/data/metabase not present")
@pytest.mark.parametrize("path", sorted(METABASE.glob("*Magnetometer*.csv")) or [None], ids=lambda p: p and p.name[:30])
def test_real_recording_without_figure_eight_is_refused(path):
    """The MetaBase exports are everyday recordings, not calibrations: the sensors never turned far."""
    assert path is not None, f"no magnetometer export in {METABASE}"
    mag_ut = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(3, 4, 5)) * 1e6  # T -> µT
    with pytest.raises(ValueError, match="too few directions"):
        fit_ellipsoid(mag_ut)
    with pytest.raises(ValueError, match="too few directions"):
        fit_ellipsoid(mag_ut, model="sphere")
