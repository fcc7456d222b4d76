"""The ``chakamo`` command line, run in-process as a user would call it."""

import json

import pytest

from app.cli import main


def test_demo_processes_a_simulated_session_and_reports_accuracy(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--cycles", "5"]) == 0
    accuracy = json.loads((tmp_path / "demo_accuracy.json").read_text())
    assert accuracy["cycles_found"] == accuracy["cycles_true"] == 5
    assert accuracy["rmse_deg"]["flexion"] < 1.0
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["cycles"]["detected"] == 5
    for name in ("report.pdf", "angles.xlsx", "quaternions.xlsx", "report.html", "scene.viser", "timeseries.npz"):
        assert (tmp_path / name).stat().st_size > 1000, name
    assert any(p.name.endswith(".csv") and "MetaWear" in p.name for p in (tmp_path / "session").iterdir())
    assert "Knee angles against the simulated truth" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["demo", "--cycles", "1"], "between 3 and 30"),
    (["process", "/no/such/folder", "--out", "OUT"], "no such session folder"),
    (["walk", "/no/such/walk.csv"], "no such file"),
    (["markov", "/no/such/file.csv", "--out", "OUT"], "no such file"),
    (["view", "/no/such/folder"], "chakamo process"),
])
def test_user_errors_exit_2_with_a_message(argv, message, tmp_path, capsys):
    argv = [a if a != "OUT" else str(tmp_path / "out") for a in argv]
    if argv[0] == "demo":
        argv += ["--out", str(tmp_path / "demo")]
    assert main(argv) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]  # progress lines may come first
    assert last.startswith(f"chakamo {argv[0]}: error:") and message in last.lower()
    assert not (tmp_path / "out").exists()
