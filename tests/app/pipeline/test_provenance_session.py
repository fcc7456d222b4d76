"""What the files say of themselves, checked against the session when it is processed (issue 14 §4): a recording of
the other leg is refused unless the side is given explicitly; recordings made weeks before the session date are
warned, translated in the reports."""

from __future__ import annotations

import json

import pytest

from app.pipeline.demo import simulate_session, write_session
from app.pipeline.process import process_folder
from app.pipeline.session import PipelineError, ProcessOptions


@pytest.fixture(scope="module")
def truth():
    return simulate_session(seed=5, side="right", n_cycles=4, accelerometer_errors=False)


def _manifest(folder, **extra):
    m = folder / "session.json"
    data = json.loads(m.read_text())
    data.update(extra)
    m.write_text(json.dumps(data))


def test_recordings_48_days_before_the_session_are_warned_in_every_language(truth, tmp_path):
    from reports.warning_text import warning_text

    write_session(tmp_path / "s", truth)
    _manifest(tmp_path / "s", date="2027-01-09")  # the demo records on 2026-11-22
    process_folder(tmp_path / "s", tmp_path / "out", reports=False)
    r = json.loads((tmp_path / "out" / "results.json").read_text())
    far = [w for w in r["quality"]["warnings"] if w["code"] == "check.date_far"]
    assert far and far[0]["params"]["days"] == 48, r["quality"]["warnings"]
    for lang in ("es", "pt"):
        text, translated = warning_text(far[0], lang, r)
        assert translated and "48" in text, (lang, text)


def test_a_left_leg_recording_on_a_right_knee_is_refused_unless_the_side_is_given(truth, tmp_path):
    write_session(tmp_path / "s", truth)
    for p in list((tmp_path / "s").glob("step-muslo-*")):  # the thigh's task files name the left leg
        p.rename(p.with_name(p.name.replace("step-muslo-", "step-muslo-izquierda-")))
    with pytest.raises(PipelineError, match="the recording says the left leg .* but the patient's knee is the right"):
        process_folder(tmp_path / "s", tmp_path / "out", reports=False)
    outcome, _ = process_folder(tmp_path / "s", tmp_path / "out", ProcessOptions(side="right"), reports=False)
    assert outcome.side == "right"


@pytest.mark.parametrize("lang,words", [("es", "pierna izquierda"), ("pt", "perna esquerda")])
def test_the_cli_refuses_the_other_leg_in_its_language(truth, tmp_path, capsys, lang, words):
    """A PipelineError carries its code (issue 14 §5): ``--lang`` renders it from the one catalogue."""
    from app.cli.main import main

    write_session(tmp_path / "s", truth)
    for p in list((tmp_path / "s").glob("step-muslo-*")):
        p.rename(p.with_name(p.name.replace("step-muslo-", "step-muslo-izquierda-")))
    assert main(["process", str(tmp_path / "s"), "--out", str(tmp_path / "out"), "--lang", lang]) == 2
    err = capsys.readouterr().err
    assert words in err and "leg" not in err, err
