"""Simulated sessions for the ingestion tests (small: a few seconds per recording)."""

from __future__ import annotations

import pytest

from estimators import simulation as sim

EPOCH0_S = 1_678_700_000.0  # 2023-03-13, the phone's clock at the session start


def simulate_streams(trajectory, *, drift_ppm: float = 0.0, starts_s=(0.003, 0.0, 0.017), seed: int = 0,
                     lever_arm_m=None, q_segment_sensor=None, epoch0_s: float = EPOCH0_S):
    """{kind: (t_s phone clock, values)} of one sensor; stamps = true times (phone clock), own start per stream."""
    clock = sim.ClockSpec(acc_start_s=starts_s[0], gyr_start_s=starts_s[1], mag_start_s=starts_s[2],
                          clock_drift_ppm=drift_ppm)
    imu = sim.simulate(trajectory, sim.ImuSpec.noise_only(clock), seed=seed, lever_arm_m=lever_arm_m,
                       q_segment_sensor=q_segment_sensor)
    kinds = (("acc", imu.acc), ("gyr", imu.gyr), ("mag", imu.mag))
    return {k: (epoch0_s + s.t_true_s, s.values) for k, s in kinds}, imu


def simulate_session(seed: int = 0, drift_ppm=(0.0, 8000.0), duration_s: float = 4.0):
    """{(segment, role): streams} for 2 sensors × 4 roles, the shank's clock ~0.8 % fast."""
    task = sim.step_up(n_cycles=1, step_height_m=0.17, side="right", seed=seed)
    postures = {"standing": sim.standing(duration_s), "lying": sim.supine(duration_s), "task": task}
    out, imus = {}, {}
    for j, segment in enumerate(("thigh", "shank")):
        fig8 = sim.figure_eight(max(duration_s, 8.0), seed=seed + j)
        out[(segment, "mag_calibration")], _ = simulate_streams(fig8, drift_ppm=drift_ppm[j], seed=seed + j)
        for role, leg in postures.items():
            streams, imu = simulate_streams(getattr(leg, segment), drift_ppm=drift_ppm[j], seed=seed + 10 * j,
                                            lever_arm_m=getattr(leg, f"{segment}_lever_arm_m"),
                                            epoch0_s=EPOCH0_S + (100.0 if role == "task" else 0.0))
            out[(segment, role)] = streams
            imus[(segment, role)] = imu
    return out, imus


@pytest.fixture(scope="session")
def sim_session():
    return simulate_session()


@pytest.fixture
def folder(session_dir, tmp_path):
    """A private copy of the module's ``session_dir`` (a test may damage it)."""
    import shutil

    d = tmp_path / "s"
    shutil.copytree(session_dir, d)
    return d
