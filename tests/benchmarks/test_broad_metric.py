"""The BROAD error metric (benchmarks/broad.py) on synthetic orientations with known errors.

The tests that read ``../shared/data/broad`` skip when it is absent; the others need nothing outside the repo.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import broad
from estimators import quaternion as quat

N = 3000
DEG = np.pi / 180.0


def _motion(n: int = N, seed: int = 0) -> np.ndarray:
    """A smooth trajectory that visits many orientations (q_ENU_marker)."""
    t = np.linspace(0.0, 30.0, n)
    rng = np.random.default_rng(seed)
    freq = rng.uniform(0.05, 0.3, size=(3, 2))
    amp = rng.uniform(0.5, 1.5, size=(3, 2))
    rotvec = np.stack([amp[i, 0] * np.sin(2 * np.pi * freq[i, 0] * t) + amp[i, 1] * np.cos(2 * np.pi * freq[i, 1] * t + i)
                       for i in range(3)], axis=1)
    return quat.exp(rotvec)


def _z(angle_deg: float) -> np.ndarray:
    return quat.from_axis_angle([0.0, 0.0, 1.0], angle_deg * DEG)


def _x(angle_deg: float) -> np.ndarray:
    return quat.from_axis_angle([1.0, 0.0, 0.0], angle_deg * DEG)


@pytest.fixture
def ref() -> np.ndarray:
    return _motion()


@pytest.fixture
def movement() -> np.ndarray:
    m = np.ones(N, dtype=bool)
    m[:200] = False
    return m


@pytest.mark.parametrize("mode", ["9d", "6d"])
@pytest.mark.parametrize("align", ["broad", "full"])
def test_identical_orientations_score_zero(ref, movement, mode, align):
    e = broad.broad_errors(ref, ref, movement, mode=mode, align=align)
    assert e.total_deg < 1e-5 and e.heading_deg < 1e-5 and e.inclination_deg < 1e-5
    assert e.n_samples == movement.sum()


def test_sign_of_quaternions_does_not_matter(ref, movement):
    flipped = ref * np.where(np.arange(N) % 2 == 0, 1.0, -1.0)[:, None]
    assert broad.broad_errors(flipped, ref, movement).total_deg < 1e-5


def test_constant_tilt_error_is_all_inclination(ref, movement):
    est = quat.multiply(_x(3.0), ref)  # the estimate's vertical is tilted 3° in the earth frame
    e = broad.broad_errors(est, ref, movement, mode="9d")
    assert e.total_deg == pytest.approx(3.0, abs=1e-6)
    assert e.inclination_deg == pytest.approx(3.0, abs=1e-6)
    assert e.heading_deg < 1e-6


def test_constant_heading_error_is_all_heading_in_9d(ref, movement):
    est = quat.multiply(_z(5.0), ref)
    e = broad.broad_errors(est, ref, movement, mode="9d")
    assert e.total_deg == pytest.approx(5.0, abs=1e-6)
    assert e.heading_deg == pytest.approx(5.0, abs=1e-6)
    assert e.inclination_deg < 1e-6


def test_combined_error_splits_into_heading_and_inclination(ref, movement):
    est = quat.multiply(quat.multiply(_x(4.0), _z(7.0)), ref)  # swing (tilt) ⊗ twist (heading)
    e = broad.broad_errors(est, ref, movement, mode="9d")
    assert e.heading_deg == pytest.approx(7.0, abs=1e-6)
    assert e.inclination_deg == pytest.approx(4.0, abs=1e-6)
    assert e.total_deg > 7.0


@pytest.mark.parametrize("offset_deg", [2.0, 120.0, -170.0])
def test_6d_ignores_a_constant_heading_offset(ref, movement, offset_deg):
    est = quat.multiply(_z(offset_deg), ref)
    e = broad.broad_errors(est, ref, movement, mode="6d")
    assert e.total_deg < 1e-5
    assert e.heading_offset_deg == pytest.approx(offset_deg, abs=1e-6)
    # ... but keeps a tilt error on top of it
    e = broad.broad_errors(quat.multiply(_x(3.0), est), ref, movement, mode="6d")
    assert e.total_deg == pytest.approx(3.0, abs=1e-3)
    assert e.inclination_deg == pytest.approx(3.0, abs=1e-3)


def test_6d_removes_only_the_constant_part_of_a_heading_error(ref, movement):
    drift_deg = np.linspace(-4.0, 4.0, N)  # heading drifting linearly about a mean offset of 30°
    est = quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], (30.0 + drift_deg) * DEG), ref)
    e = broad.broad_errors(est, ref, movement, mode="6d")
    expected = np.sqrt(np.mean(drift_deg[movement] ** 2))
    assert e.heading_deg == pytest.approx(expected, rel=0.02)
    assert e.inclination_deg < 1e-6


def test_full_alignment_removes_body_misalignment_and_heading_offset(ref, movement):
    q_marker_imu = quat.from_euler([25.0 * DEG, -40.0 * DEG, 70.0 * DEG], "ZYX")
    est = quat.multiply(quat.multiply(_z(-35.0), ref), q_marker_imu)
    assert broad.broad_errors(est, ref, movement, mode="9d").total_deg > 20.0  # BROAD's 9D: data taken as aligned
    for mode in ("9d", "6d"):
        e = broad.broad_errors(est, ref, movement, mode=mode, align="full")
        assert e.total_deg < 1e-4
        assert e.heading_offset_deg == pytest.approx(-35.0, abs=1e-4)
        assert e.body_misalignment_deg == pytest.approx(np.degrees(quat.angle_between(quat.identity(), q_marker_imu)),
                                                        abs=1e-4)


def test_full_alignment_with_noise_leaves_the_noise(ref, movement):
    rng = np.random.default_rng(3)
    noise = quat.exp(rng.normal(scale=1.0 * DEG, size=(N, 3)))  # 1° per axis, earth frame
    q_marker_imu = quat.from_euler([-10.0 * DEG, 5.0 * DEG, 160.0 * DEG], "ZYX")
    est = quat.multiply(noise, quat.multiply(quat.multiply(_z(50.0), ref), q_marker_imu))
    e = broad.broad_errors(est, ref, movement, align="full")
    assert e.total_deg == pytest.approx(np.sqrt(3.0), rel=0.05)  # RMS angle of 3 axes × 1°
    assert e.heading_offset_deg == pytest.approx(50.0, abs=0.1)


def test_missing_reference_and_rest_samples_are_not_scored(ref, movement):
    est = ref.copy()
    est[:200] = quat.multiply(_x(60.0), ref[:200])  # outside the movement phase
    gap = slice(1000, 1100)
    ref_gap = ref.copy()
    ref_gap[gap] = np.nan
    est[gap] = quat.multiply(_x(60.0), ref[gap])  # where the reference is lost
    e = broad.broad_errors(est, ref_gap, movement, mode="6d")
    assert e.total_deg < 1e-5
    assert e.n_samples == movement.sum() - 100


def test_nan_estimate_gives_nan_not_a_hidden_score(ref, movement):
    est = ref.copy()
    est[500] = np.nan
    assert np.isnan(broad.broad_errors(est, ref, movement).total_deg)


def test_bad_arguments_are_reported(ref, movement):
    with pytest.raises(ValueError, match="mode"):
        broad.broad_errors(ref, ref, movement, mode="3d")
    with pytest.raises(ValueError, match="align"):
        broad.broad_errors(ref, ref, movement, align="some")
    with pytest.raises(ValueError, match="shapes"):
        broad.broad_errors(ref[:-1], ref, movement)
    with pytest.raises(ValueError, match="movement"):
        broad.broad_errors(ref, ref, np.zeros(N, dtype=bool))


def _synthetic_trial(name: str, group: str, seed: int) -> broad.Trial:
    q = _motion(seed=seed)
    zeros = np.zeros((N, 3))
    return broad.Trial(name=name, group=group, acc=zeros + [0.0, 0.0, 9.81], gyr=zeros, mag=zeros + [0.0, 20.0, -40.0],
                       quat_ref=q, movement=np.ones(N, dtype=bool), fs_hz=100.0)


def test_evaluate_runs_each_trial_and_passes_mag_only_in_9d():
    trial_list = [_synthetic_trial("02_undisturbed_x", "undisturbed", 1), _synthetic_trial("24_disturbed_y", "disturbed", 2)]
    seen_mag = []

    def oracle_with_tilt(acc, gyr, mag, fs_hz):
        seen_mag.append(mag is not None)
        trial = next(t for t in trial_list if t.acc is acc)
        return quat.multiply(_x(2.0), trial.quat_ref)

    rows = broad.evaluate(oracle_with_tilt, trials=trial_list, mode="9d", name="oracle")
    assert [r["trial"] for r in rows] == ["02_undisturbed_x", "24_disturbed_y"]
    assert all(r["total_deg"] == pytest.approx(2.0, abs=1e-6) and r["method"] == "oracle" for r in rows)
    means = broad.group_means(rows)
    assert means["undisturbed"]["inclination_deg"] == pytest.approx(2.0, abs=1e-6)
    rows6 = broad.evaluate(oracle_with_tilt, trials=trial_list, mode="6d")
    assert seen_mag == [True, True, False, False]
    assert len(rows6) == 2 and "per trial" in broad.format_tables(rows + rows6, "9d")


def test_trials_warns_and_yields_nothing_without_data(tmp_path, monkeypatch):
    monkeypatch.setenv(broad.DATA_ENV, str(tmp_path))
    assert broad.data_dir() is None
    with pytest.warns(UserWarning, match="BROAD data not found"):
        assert list(broad.trials()) == []
    assert broad.main(["--mode", "9d"]) == 2


# ---------------------------------------------------------------- real data (skips when ../shared is absent)
needs_data = pytest.mark.skipif(broad.data_dir() is None, reason="BROAD data (../shared/data/broad) not present")


@needs_data
def test_load_trial_reads_the_fields():
    path = sorted(broad.data_dir().glob("02_*.hdf5"))[0]
    trial = broad.load_trial(path)
    assert trial.group == "undisturbed" and trial.number == "02"
    assert trial.acc.shape == trial.gyr.shape == trial.mag.shape == (trial.n, 3)
    assert trial.quat_ref.shape == (trial.n, 4) and trial.movement.dtype == bool
    assert trial.fs_hz == pytest.approx(285.714, abs=0.01)
    valid = np.isfinite(trial.quat_ref).all(axis=1)
    assert np.allclose(np.linalg.norm(trial.quat_ref[valid], axis=1), 1.0, atol=1e-6)
    # at rest at the start the accelerometer reads about +9.81 along the reference's up axis
    up_in_sensor = quat.rotate(quat.conjugate(trial.quat_ref[valid][0]), [0.0, 0.0, 1.0])
    assert np.dot(trial.acc[np.flatnonzero(valid)[0]], up_in_sensor) > 9.5


@needs_data
def test_vqf_offline_scores_as_published_on_one_trial():
    vqf = pytest.importorskip("vqf")
    path = sorted(broad.data_dir().glob("02_*.hdf5"))[0]
    trial = broad.load_trial(path)
    out = vqf.offlineVQF(trial.gyr, trial.acc, trial.mag, 1.0 / trial.fs_hz)
    e9 = broad.broad_errors(out["quat9D"], trial, mode="9d")
    e6 = broad.broad_errors(out["quat6D"], trial, mode="6d")
    assert 0.7 < e9.total_deg < 1.4  # 1.01° measured; the 10-trial mean is 1.66° (VQF paper ~1.7°)
    assert 0.3 < e6.total_deg < 0.9  # 0.56° measured
    assert e9.heading_offset_deg == 0.0  # 9D: the published alignment is kept


def test_held_out_splits_are_disjoint_halves_of_the_shared_trials():
    a, b = broad.SPLITS["A"], broad.SPLITS["B"]
    assert len(a) == len(b) == 5 and not set(a) & set(b)
    assert sorted(a + b) == ["02", "07", "10", "15", "18", "24", "27", "30", "32", "35"]
    for half in (a, b):  # both groups in each half (undisturbed 02-18, disturbed 24-35)
        assert 2 <= sum(int(n) < 22 for n in half) <= 3


def test_held_out_grids_contain_the_defaults_and_real_parameters():
    from dataclasses import fields

    from estimators.orientation import get_method

    for name, grid in broad.GRIDS.items():
        params_type = get_method(name).params_type
        names = {f.name for f in fields(params_type)}
        assert set(grid) <= names
        for key, values in grid.items():
            assert any(np.isclose(getattr(params_type(), key), v) for v in values), (name, key)
        assert len(broad._grid(name)) == int(np.prod([len(v) for v in grid.values()]))


def test_held_out_chooses_on_one_half_and_scores_the_other(monkeypatch):
    """A fake method whose error on half A is |x - 1| + 1 and on half B |x - 3| + 2: each split must pick
    the other half's worse value and report the held-out half's score, not the tuned one."""
    trials = [broad.Trial(name=f"{n}_x", group="undisturbed" if int(n) < 22 else "disturbed",
                          acc=np.zeros((2, 3)), gyr=np.zeros((2, 3)), mag=np.zeros((2, 3)),
                          quat_ref=np.zeros((2, 4)), movement=np.ones(2, bool), fs_hz=100.0)
              for half in broad.SPLITS.values() for n in half]

    def fake_evaluate(fn, *, trials, mode, name="", align="broad"):
        x = fn.get("x", 0.0) if isinstance(fn, dict) else 0.0
        return [{"trial": t.name, "group": t.group, "mode": mode, "method": name, "heading_deg": 0.0,
                 "inclination_deg": 0.0,
                 "total_deg": abs(x - 1.0) + 1.0 if t.number in broad.SPLITS["A"] else abs(x - 3.0) + 2.0}
                for t in trials]

    monkeypatch.setattr(broad, "evaluate", fake_evaluate)
    monkeypatch.setattr(broad, "project_method", lambda name, **params: params)
    monkeypatch.setattr(broad, "GRIDS", {"fake": {"x": (1.0, 3.0)}})
    rows = [r for r in broad.held_out(["fake"], trials, ["9d"]) if r["method"] == "fake"]
    by_split = {r["tuned_on"]: r for r in rows}
    assert by_split["A"]["params"] == {"x": 1.0} and by_split["A"]["tuned_deg"] == 1.0
    assert by_split["A"]["all"] == 4.0  # scored on B with x = 1: |1 - 3| + 2
    assert by_split["B"]["params"] == {"x": 3.0} and by_split["B"]["tuned_deg"] == 2.0
    assert by_split["B"]["all"] == 3.0  # scored on A with x = 3: |3 - 1| + 1
    assert "fake" in broad.format_held_out(rows)
