"""The ``chakamo`` command line, run in-process as a user would call it."""

import json

from app.cli import main
from estimators.orientation import METHODS


def test_demo_writes_every_filter_with_its_accuracy(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--duration", "15"]) == 0
    result = json.loads((tmp_path / "filters.json").read_text())
    assert {row["method"] for row in result["filters"]} == set(METHODS)
    calibration = result["calibration"]["magnetometer"]
    assert 20.0 < calibration["field_ut"] < 70.0
    # madgwick on the calibrated field stays within a few degrees of the truth
    madgwick_9d = next(r for r in result["filters"] if r["method"] == "madgwick" and r["mode"] == "9d")
    assert madgwick_9d["total_rmse_deg"] < 5.0
    assert "total RMSE" in capsys.readouterr().out


def test_demo_rejects_a_too_short_motion(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--duration", "2"]) == 2
    assert "at least 10 s" in capsys.readouterr().err
    assert not (tmp_path / "filters.json").exists()
