"""``app.research.markov.run_markov`` on a simulated thigh + shank CSV (the documented format)."""

import csv
import json

import numpy as np
import pytest

from app.research.markov import read_markov_csv, run_markov
from estimators.simulation.exoskeleton import gait_chain, simulate_chain


def _write(path, with_encoder=True, n_seconds=20.0):
    ch = gait_chain(n_seconds + 1.0, n_segments=2, seed=4, cadence_hz=0.5, still_s=2.0)
    # the record starts with the leg still and upright, as the format requires
    g = simulate_chain(ch, 50.0, seed=4)
    sl = slice(25, None)
    t = g[0].t_true_s[sl] - g[0].t_true_s[25]
    knee = ch.joint_at(g[0].t_true_s[sl])[:, 0]
    header = ["t_s"] + [f"{s}_{k}_{a}" for s in ("thigh", "shank") for k in ("acc", "gyr") for a in "xyz"]
    if with_encoder:
        header.append("knee_enc_rad")
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        fh.write("# simulated exoskeleton walk\n")
        w.writerow(header)
        for k in range(len(t)):
            row = [t[k]] + list(g[0].acc[25 + k]) + list(g[0].gyr[25 + k]) + list(g[1].acc[25 + k]) + \
                list(g[1].gyr[25 + k])
            if with_encoder:
                row.append("" if k % 2 else knee[k])
            w.writerow([f"{v:.6f}" if v != "" else "" for v in row])
    return knee


@pytest.mark.parametrize("method", ["sme", "smea", "mjls", "kf"])
def test_run_markov_writes_angles_and_occupancy(tmp_path, method):
    src = tmp_path / "walk.csv"
    knee = _write(src)
    summary = run_markov(src, tmp_path / "out", method=method)
    assert summary["method"] == method
    assert abs(sum(summary["occupancy"].values()) - 1.0) < 1e-9
    assert list(summary["occupancy"]) == summary["markov_state_labels"]   # one naming of the states
    js = json.loads((tmp_path / "out" / "markov.json").read_text())
    assert js["fs_hz"] == pytest.approx(50.0)
    with open(tmp_path / "out" / "angles.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(knee)
    est = np.array([float(r["knee_deg"]) for r in rows])
    # the angles are zero at the start pose: compare changes of the knee angle
    err = (est - est[0]) - np.degrees(knee - knee[0])
    # the standard KF has no encoder and no joint constraint: its knee angle is the loosest
    assert np.sqrt(np.mean(err[60:] ** 2)) < (10.0 if method == "kf" else 4.0)


def test_auto_picks_smea_without_encoder(tmp_path):
    src = tmp_path / "walk.csv"
    _write(src, with_encoder=False, n_seconds=8.0)
    assert run_markov(src, tmp_path / "o")["method"] == "smea"


def test_format_errors(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("t_s,thigh_acc_x\n0,1\n0.02,1\n0.04,1\n")
    with pytest.raises(ValueError, match="thigh"):
        read_markov_csv(bad)
    src = tmp_path / "walk.csv"
    _write(src, with_encoder=False, n_seconds=4.0)
    with pytest.raises(ValueError, match="encoder"):
        run_markov(src, tmp_path / "o", method="sme")
    with pytest.raises(ValueError, match="method"):
        run_markov(src, tmp_path / "o", method="magic")
    with pytest.raises(ValueError, match="no such file"):
        run_markov(tmp_path / "missing.csv", tmp_path / "o")
