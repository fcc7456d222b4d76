"""``chakamo walk`` back end: IEZ ingestion (units, ranges, clock gaps, saturation, malformed files) and run_walk."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from app.research.walk import run_walk
from app.research.walk_ingestion import ACC_COUNTS_PER_G, GYR_COUNTS_PER_DEG_S, range_codes_from_name, read_iez, read_walk
from estimators.simulation.imu import simulate_on_grid
from estimators.simulation.motions import walking_foot
from estimators.simulation.spec import ImuSpec

IEZ_DIR = Path(__file__).resolve().parents[4] / "shared" / "data" / "iez"


def _write_iez(path: Path, t_ms, acc_counts, gyr_counts) -> Path:
    rows = []
    for k in range(len(t_ms)):
        vals = [int(t_ms[k]), *acc_counts[k], *gyr_counts[k], *acc_counts[k], *gyr_counts[k]]
        rows.append(",".join(str(int(v)) for v in vals))
    path.write_bytes(("\r\n\r\n".join(rows) + "\r\n\r\n").encode())
    return path


@pytest.fixture(scope="module")
def sim_iez(tmp_path_factory):
    """A simulated closed rectangle written as an IEZ file with ranges ±16 g / ±2000 °/s (codes 3, 3)."""
    walk = walking_foot(path="rectangle", seed=4)
    g = simulate_on_grid(walk.trajectory, ImuSpec.perfect(), fs_hz=100.0)
    acc_c = np.round(g.acc / 9.81 * ACC_COUNTS_PER_G[3])
    gyr_c = np.round(np.rad2deg(g.gyr) * GYR_COUNTS_PER_DEG_S[3])
    t_ms = 5000 + np.round(g.t_s * 1000)
    path = tmp_path_factory.mktemp("iez") / "conf-3333-sim-01.csv"
    return walk, g, _write_iez(path, t_ms, acc_c, gyr_c)


def test_units_ranges_and_both_sensors(tmp_path):
    n = 50
    t = 1000 + 10 * np.arange(n)
    t[30:] += 14  # a 24 ms gap
    acc = np.tile([0, 0, 16384], (n, 1))
    gyr = np.tile([131, 0, -131], (n, 1))
    p = _write_iez(tmp_path / "conf-0000-x.csv", t, acc, gyr)
    r = read_iez(p, 1)
    np.testing.assert_allclose(r.acc[0], [0, 0, 9.81])
    np.testing.assert_allclose(r.gyr[0], np.deg2rad([1.0, 0, -1.0]))
    assert r.t_s[0] == 0.0 and r.dt_s[30] == pytest.approx(0.024) and r.fs_hz == pytest.approx(100.0)
    assert r.acc_range_m_s2 == pytest.approx(2 * 9.81) and r.gyr_range_rad_s == pytest.approx(np.deg2rad(250))
    assert not r.gyr_saturated.any()
    assert range_codes_from_name("conf-1302-coleta.csv") == (1, 3, 0, 2)
    r2 = read_walk(p, fmt="iez", sensor=2)
    np.testing.assert_allclose(r2.acc, r.acc)


def test_saturated_samples_flagged(tmp_path):
    n = 40
    gyr = np.zeros((n, 3), int)
    gyr[10:14, 1] = 32767
    gyr[20, 2] = -32768
    acc = np.tile([0, 0, 16384], (n, 1))
    acc[25, 0] = 32767
    r = read_iez(_write_iez(tmp_path / "conf-0000-s.csv", 10 * np.arange(n), acc, gyr), 1)
    assert np.flatnonzero(r.gyr_saturated).tolist() == [10, 11, 12, 13, 20]
    assert np.flatnonzero(r.acc_saturated).tolist() == [25]


@pytest.mark.parametrize("content, name, match", [
    ("1,2,3\r\n", "conf-0000-a.csv", "expected 13"),
    ("\n".join(["10,1,2,3,4,5,x,1,2,3,4,5,6"] * 20), "conf-0000-b.csv", "not an integer"),
    ("\n".join([f"{10 * k},1,2,3,4,5,6,1,2,3,4,5,6" for k in range(20)]), "walk.csv", "conf-ABCD"),
    ("\n".join([f"{10 * (k % 10)},1,2,3,4,5,6,1,2,3,4,5,6" for k in range(20)]), "conf-0000-c.csv", "does not increase"),
    ("\n".join([f"{10 * k},1,2,3,4,5,99999,1,2,3,4,5,6" for k in range(20)]), "conf-0000-d.csv", "int16"),
    ("10,1,2,3,4,5,6,1,2,3,4,5,6\n", "conf-0000-e.csv", "only 1 samples"),
])
def test_malformed_files_rejected(tmp_path, content, name, match):
    p = tmp_path / name
    p.write_text(content)
    with pytest.raises(ValueError, match=match):
        read_iez(p, 1)


def test_bad_sensor_and_format(tmp_path):
    p = _write_iez(tmp_path / "conf-0000-z.csv", 10 * np.arange(20), np.zeros((20, 3)), np.zeros((20, 3)))
    with pytest.raises(ValueError, match="sensor must be 1 or 2"):
        read_iez(p, 3)
    with pytest.raises(ValueError, match="unknown walk format"):
        read_walk(p, fmt="xls")


def test_run_walk_json_and_svg(sim_iez, tmp_path):
    walk, g, path = sim_iez
    out = run_walk(path, fmt="iez", sensor=2, json_out=tmp_path / "w.json", plot_out=tmp_path / "w.svg")
    data = json.loads((tmp_path / "w.json").read_text())
    assert set(data["metrics"]) >= {"ep", "ed", "ed_stance", "ea_m"}
    assert data["method"] == "chakamo" and data["input"]["sensor"] == 2
    assert len(data["trajectory"]["t_s"]) == len(data["trajectory"]["pos_m"]) == len(g.t_s)
    assert data["metrics"]["ep"] < 0.005 and abs(data["metrics"]["ed_stance"]) < 0.01
    true_len = np.linalg.norm(np.diff(walk.placements_m[:, :2], axis=0), axis=1)
    assert len(data["strides"]) == len(true_len)
    np.testing.assert_allclose([s["length_m"] for s in data["strides"]], true_len, atol=0.03)
    assert out["summary"]["cadence_steps_min"] == pytest.approx(2 * out["summary"]["cadence_strides_min"])
    root = ET.fromstring((tmp_path / "w.svg").read_text())
    assert root.tag.endswith("svg") and any(e.tag.endswith("polyline") for e in root)


def test_svg_title_with_markup_characters_stays_valid(sim_iez, tmp_path):
    _, _, path = sim_iez
    odd = tmp_path / "conf-3333-a&b<c>.csv"
    odd.write_bytes(path.read_bytes())
    run_walk(odd, plot_out=tmp_path / "w.svg")
    root = ET.fromstring((tmp_path / "w.svg").read_text())  # an unescaped & or < would not parse
    (text,) = [e for e in root if e.tag.endswith("text")]
    assert text.text.startswith(f"{odd.name} sensor 1")


@pytest.mark.skipif(not IEZ_DIR.is_dir(), reason="../shared/data/iez not present")
def test_real_iez_file_reads_and_flags_gyroscope_saturation():
    files = sorted(IEZ_DIR.glob("conf-3030-*.csv"))
    if not files:
        pytest.skip("no conf-3030 walk")
    r = read_iez(files[0], 1)
    assert r.gyr_saturated.sum() > 100          # ±250 °/s clips every swing
    assert np.linalg.norm(r.acc[:100].mean(axis=0)) == pytest.approx(9.81, rel=0.06)
