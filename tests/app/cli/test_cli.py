"""The ``chakamo`` command line, run in-process as a user would call it."""

import json

import numpy as np
import pytest

from app.cli.main import main
from app.pipeline.demo import simulate_session


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
    # the ground truth it was scored against, re-simulated here from the same seed
    truth = simulate_session(seed=7, side="right", n_cycles=5).motion
    with np.load(tmp_path / "demo_truth.npz") as z:
        assert list(z["angle_names"]) == ["flexion", "adduction", "internal_rotation"]
        assert len(z["cycles_s"]) == accuracy["cycles_true"] == 5 and z["phases_s"].shape == (5, 4)
        np.testing.assert_allclose(z["cycles_s"], truth.cycles_s)
        np.testing.assert_allclose(z["phases_s"], truth.phases_s)
        np.testing.assert_allclose(z["t_s"], truth.t_s)
        np.testing.assert_allclose(z["knee_angles_deg"], np.rad2deg(truth.knee_angles_rad))
        assert 40.0 < z["knee_angles_deg"][:, 0].max() < 100.0  # degrees
        assert str(z["side"]) == "right"
    assert not [p for p in tmp_path.parent.iterdir() if p.name.startswith(f".{tmp_path.name}.")]  # no staging left


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


@pytest.mark.parametrize("lang, expected", [("en", "no such session folder"), ("es", "no existe esa carpeta"),
                                            ("pt", "essa pasta de sessão não existe")])
def test_a_file_problem_is_told_in_the_language_asked_for(lang, expected, tmp_path, capsys):
    """``--lang`` gives the report's language and the messages' (issue 14 §5)."""
    from app.pipeline.ingestion.messages import render

    assert main(["process", str(tmp_path / "nope"), "--out", str(tmp_path / "out"), "--lang", lang]) == 2
    err = capsys.readouterr().err
    assert render("session.no_folder", {"file": tmp_path / "nope"}, lang) in err and expected in err, err


def test_process_excludes_the_cycles_named_and_says_who_and_why(tmp_path, capsys):
    """``--exclude-cycles``: the cycles leave the statistics with the clinician's reason, not as the pipeline's
    rejections; a cycle that was not detected, every cycle, or a malformed list is refused, nothing written."""
    from app.pipeline.demo import write_session

    session = tmp_path / "session"
    write_session(session, simulate_session(seed=7, side="right", n_cycles=4))
    out = tmp_path / "out"
    assert main(["process", str(session), "--out", str(out), "--exclude-cycles", "2", "--exclude-reason",
                 "lost balance", "--lang", "en"]) == 0
    r = json.loads((out / "results.json").read_text())
    assert r["cycles"]["detected"] == 4 and r["cycles"]["accepted"] == 3 and 1 not in r["cycles"]["accepted_indices"]
    assert [(e["cycle"], e["knee"], e["reason"]) for e in r["cycles"]["excluded"]] == [(2, None, "lost balance")]
    assert {(x["index"], x["reason"]) for x in r["cycles"]["rejected"]} == {(1, "excluded_by_clinician")}
    assert not [w for w in r["quality"]["warnings"] if w["code"] == "cycles_rejected"]
    # the reports name the clinician's exclusion apart from the pipeline's rejections, and the technical notes apart
    import shutil
    import subprocess

    html = (out / "report.html").read_text(encoding="utf-8")
    assert "Cycle 2 excluded by the clinician" in html and "lost balance" in html
    assert '<details class="technical">' in html and r["quality"]["technical_notes"]
    if shutil.which("pdftotext"):
        text = " ".join(subprocess.run(["pdftotext", str(out / "report.pdf"), "-"], capture_output=True, text=True,
                                       check=True).stdout.split())
        assert "Cycle 2 excluded by the clinician" in text and "lost balance" in text
        assert "4 detected, 3 accepted, 0 rejected." in text
        notes = text.split("Technical notes on reading the files", 1)
        assert len(notes) == 2 and "common span" in notes[1] and "common span" not in notes[0]
    capsys.readouterr()
    for bad, words in (("9", "cycle 9 cannot be excluded: 4 cycles were detected"),
                       ("1,2,3,4", "leaves none of the 4 detected"), ("two", "--exclude-cycles: 'two'"),
                       ("left:2", "the left knee")):
        assert main(["process", str(session), "--out", str(tmp_path / "bad"), "--exclude-cycles", bad]) == 2
        assert words in capsys.readouterr().err.strip().splitlines()[-1], bad
        assert not (tmp_path / "bad").exists()


def test_process_progress_and_exclusion_refusal_speak_the_language_of_lang(tmp_path, capsys):
    """``chakamo process --lang``: the progress lines on stderr name the pipeline's stages in that language (they
    were English whatever --lang said), and a malformed ``--exclude-cycles`` is refused in it, nothing written."""
    from app.pipeline.demo import write_session

    session = tmp_path / "session"
    write_session(session, simulate_session(seed=7, side="right", n_cycles=4))
    assert main(["process", str(session), "--out", str(tmp_path / "out"), "--lang", "pt"]) == 0
    err = capsys.readouterr().err
    for line in ("[  0 %] leitura", "] acelerómetro", "] magnetómetro", "] segmentos", "] joelho", "[100 %] concluído"):
        assert line in err, err
    assert "] read" not in err and "] done" not in err, err
    # the two orientation stages ("orientation thigh", two words) were English whatever --lang said
    assert "] orientação do sensor da coxa" in err and "] orientação do sensor da perna" in err, err
    assert "orientation" not in err, err
    assert main(["process", str(session), "--out", str(tmp_path / "out_es"), "--lang", "es"]) == 0
    err = capsys.readouterr().err
    assert "] orientación del sensor del muslo" in err and "] orientación del sensor de la pierna" in err, err
    assert "orientation" not in err, err
    for lang, words in (("en", "--exclude-cycles: 'two' is not a cycle number"),
                        ("es", "--exclude-cycles: 'two' no es un número de ciclo"),
                        ("pt", "--exclude-cycles: 'two' não é um número de ciclo")):
        assert main(["process", str(session), "--out", str(tmp_path / "bad"), "--exclude-cycles", "two",
                     "--lang", lang]) == 2
        assert words in capsys.readouterr().err.strip().splitlines()[-1], lang
        assert not (tmp_path / "bad").exists()
