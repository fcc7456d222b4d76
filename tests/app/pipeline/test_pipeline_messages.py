"""PipelineError messages from one catalogue in es/en/pt (issue 14 §5), as the ingestion's."""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import pytest

from app.pipeline.ingestion.messages import CATALOGUE, LANGUAGES, placeholders
from app.pipeline.messages import PIPELINE_CATALOGUE, message_dict
from app.pipeline.session import PipelineError, ProcessOptions

SRC = Path(__file__).resolve().parents[3] / "app"


def test_every_code_has_three_languages_with_the_same_placeholders():
    for code, entry in PIPELINE_CATALOGUE.items():
        assert set(entry) == set(LANGUAGES), code
        assert placeholders(entry["es"]) == placeholders(entry["en"]) == placeholders(entry["pt"]), code
        assert code not in CATALOGUE, code   # one definition of each code


def test_every_code_raised_has_its_texts():
    used = set()
    for p in (SRC / "pipeline").glob("*.py"):
        used |= set(re.findall(r'PipelineError\(\s*"([a-z_]+\.[a-z_]+)"', p.read_text()))
    for p in (SRC / "jobs").glob("*.py"):
        used |= set(re.findall(r'render_message\(\s*"([a-z_]+\.[a-z_]+)"', p.read_text()))
    assert len(used) >= 8 and not used - set(PIPELINE_CATALOGUE), sorted(used - set(PIPELINE_CATALOGUE))


def test_an_option_error_in_each_language_and_through_pickle():
    with pytest.raises(PipelineError) as err:
        ProcessOptions(heading="compass")
    exc = err.value
    assert exc.code == "pipeline.bad_option" and "'compass'" in str(exc) and "auto" in str(exc)
    assert "debe ser uno de" in exc.message("es") and "deve ser um de" in exc.message("pt")
    again = pickle.loads(pickle.dumps(exc))
    assert (again.code, again.params, str(again)) == (exc.code, exc.params, str(exc))


def test_a_diagnosis_cause_is_rendered_by_the_reports_warning_catalogue():
    cause = {"code": "warning.sensors_swapped", "message": "knee flexion reads below −15° ...",
             "params": {"pct": 80.0, "median_deg": -40.0, "swapped_median_deg": 35.0}}
    d = message_dict("pipeline.implausible_angles", {"thigh_files": "a.csv", "shank_files": "b.csv", "cause": cause})
    assert d["message"]["en"].startswith("a.csv (thigh) and b.csv (shank): knee flexion reads below")
    assert "intercambiados" in d["message"]["es"] and "80 %" in d["message"]["es"]
    assert "trocados" in d["message"]["pt"]


def test_plain_text_stays_in_every_language():
    exc = PipelineError("something odd happened")
    assert exc.code == "text" and exc.message("es") == "something odd happened"
