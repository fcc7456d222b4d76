"""The split of a continuous recording confirmed or moved by the clinician and stored on the server (issue 14 §3a),
and the session check's sentences in every language (issue 14 §5).

Truth: the simulator's protocol (:func:`estimators.simulation.protocol.leg_protocol`) joined at known times, as
``tests/app/pipeline/test_continuous_session.py`` builds it; the cut the test moves is checked against the seconds
it stored, and the recording's parts against the truth spans."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "pipeline"))
from test_continuous_session import _continuous, _write  # noqa: E402

from web_helpers import clinic_token, make_settings, new_session  # noqa: E402


@pytest.fixture(scope="module")
def continuous():
    return _continuous(seed=1, n_cycles=4)


@pytest.fixture
def uploaded(tmp_path, continuous):
    """A session holding each sensor's continuous recording (uploaded with ``role=continuous``)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    streams, _, truth = continuous
    folder = _write(tmp_path / "files", streams, word="")
    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "S")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
        for seg in ("thigh", "shank"):
            word = "muslo" if seg == "thigh" else "pierna"
            files = [("files", (p.name, p.read_bytes(), "text/csv")) for p in sorted(folder.glob(f"{word}-*.csv"))]
            r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files,
                       data={"segment": seg, "role": "continuous"})
            assert r.status_code == 201, r.text
        yield c, h, sid, r.json()["ingestion"], truth, settings


def test_the_check_shows_each_sensors_cuts_with_a_trace(uploaded):
    _, _, _, ingestion, truth, _ = uploaded
    assert ingestion["ok"] is True, ingestion
    assert set(ingestion["splits"]) == {"thigh", "shank"} and ingestion["confirmed_split"] is None
    for seg, split in ingestion["splits"].items():
        assert split["how"] == "role"
        assert split["trace_hz"] == 4.0
        assert abs(len(split["trace"]) / split["trace_hz"] - split["duration_s"]) < 0.5
        for role in ("standing", "lying", "task"):   # the automatic cuts, against the simulator's spans
            a, b = split["spans_s"][role]
            ta, tb = truth[seg][role]
            assert a < b and abs(a - ta) < 1.0, (seg, role, (a, b), (ta, tb))
        # the trace is still where the postures are and moving in the task (what the clinician reads)
        hz = split["trace_hz"]
        a, b = split["spans_s"]["standing"]
        still = max(split["trace"][int(a * hz) + 2:int(b * hz) - 2])
        moving = max(split["trace"][int(split["spans_s"]["task"][0] * hz):])
        assert still < 0.1 < moving


def test_the_clinicians_cut_is_stored_on_the_server_and_used(uploaded):
    c, h, sid, ingestion, truth, settings = uploaded
    spans = {seg: dict(split["spans_s"]) for seg, split in ingestion["splits"].items()}
    a, b = spans["thigh"]["standing"]
    moved = [round(a + 3.0, 1), round(b - 3.0, 1)]
    spans["thigh"]["standing"] = moved
    r = c.put(f"/api/v1/sessions/{sid}/split", headers=h, json={"split": spans})
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["ok"] is True and answer["confirmed_split"]["thigh"]["standing"] == moved
    assert answer["splits"]["thigh"]["how"] == "session.json"
    assert answer["splits"]["thigh"]["spans_s"]["standing"] == moved
    # stored by the server: a new read of the session (another browser) sees it
    session = c.get(f"/api/v1/sessions/{sid}", headers=h).json()
    assert session["ingestion"]["confirmed_split"]["thigh"]["standing"] == moved
    assert session["ingestion"]["splits"]["thigh"]["spans_s"]["standing"] == moved
    # and the processing reads it: the session.json the job materialises holds the stored cuts
    from app.store.database import Database
    from app.store.models import KneeSession
    from app.store.workspace import build_manifest

    with Database(settings.db_url).session() as db:
        row = db.get(KneeSession, sid)
        manifest = build_manifest(row, row.patient, list(row.recordings))
    assert manifest["split"]["thigh"]["standing"] == moved
    # back to the automatic cuts
    r = c.put(f"/api/v1/sessions/{sid}/split", headers=h, json={"split": None})
    assert r.status_code == 200 and r.json()["confirmed_split"] is None
    assert r.json()["splits"]["thigh"]["how"] == "role"


@pytest.mark.parametrize("bad", [{"thigh": {"standing": [30, 10]}}, {"thigh": {"sitting": [1, 2]}},
                                 {"knee": {"standing": [1, 2]}}])
def test_a_malformed_cut_is_refused_and_nothing_stored(uploaded, bad):
    c, h, sid, _, _, _ = uploaded
    r = c.put(f"/api/v1/sessions/{sid}/split", headers=h, json={"split": bad})
    assert r.status_code in (400, 422), r.text
    assert c.get(f"/api/v1/sessions/{sid}", headers=h).json()["ingestion"]["confirmed_split"] is None


def test_every_sentence_of_the_check_comes_in_every_language(uploaded):
    _, _, _, ingestion, _, _ = uploaded
    texts = ingestion["message_texts"]
    assert len(texts) == len(ingestion["messages"]) > 0
    assert [t["en"] for t in texts] == ingestion["messages"]
    recognised = [t for t in texts if t["en"].startswith("thigh task:")]
    assert recognised and recognised[0]["es"].startswith("muslo tarea:") and "segmento según" in recognised[0]["es"]
    assert recognised[0]["pt"].startswith("coxa tarefa:") and "segmento segundo" in recognised[0]["pt"]
    split_notes = [t for t in texts if "one continuous recording, split into" in t["en"]]
    assert len(split_notes) == 2
    assert all("dividida en" in t["es"] and "dividida em" in t["pt"] for t in split_notes)


def test_a_refused_check_is_in_every_language(tmp_path):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "R")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
        r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h,
                   files=[("files", ("muslo-tarea.csv", b"time (s),acc_x (g)\n", "text/csv"))])
        assert r.status_code == 201, r.text
        ing = r.json()["ingestion"]
    assert ing["ok"] is False and ing["error_message"]["en"] == ing["error"]
    assert ing["error_message"]["es"] != ing["error_message"]["en"] != ing["error_message"]["pt"]


def test_a_four_sensor_sessions_cut_is_moved_per_knee(tmp_path, continuous):
    """Both knees' continuous recordings (file names say the side): the check keys each sensor's cuts by knee
    (``left_thigh`` …); a moved cut of one knee's sensor is stored under that key, refused before, and the redone
    check applies it to that sensor only."""
    from fastapi.testclient import TestClient

    from app.pipeline.ingestion.metabase import write_recording_metabase
    from app.web.main import create_app

    streams, _, _ = continuous
    words = {"left": "izquierda", "right": "derecha", "thigh": "muslo", "shank": "pierna"}
    macs = {"left": "D4F1A2B3C4E1", "right": "D4F1A2B3C4E2"}
    folder = tmp_path / "files"
    folder.mkdir()
    for side in ("left", "right"):
        for seg in ("thigh", "shank"):
            write_recording_metabase(folder, f"{words[seg]}-{words[side]}-ML1-13032023-1",
                                     macs[side][:-2] + ("A" if seg == "thigh" else "B") + macs[side][-1], streams[seg])
    settings = make_settings(tmp_path / "data")
    h = clinic_token(settings, "S")
    with TestClient(create_app(settings)) as c:
        _, sid = new_session(c, h)
        for side in ("left", "right"):
            for seg in ("thigh", "shank"):
                files = [("files", (p.name, p.read_bytes(), "text/csv"))
                         for p in sorted(folder.glob(f"{words[seg]}-{words[side]}-*.csv"))]
                r = c.post(f"/api/v1/sessions/{sid}/recordings", headers=h, files=files,
                           data={"segment": seg, "role": "continuous"})
                assert r.status_code == 201, r.text
        ingestion = r.json()["ingestion"]
        assert ingestion["ok"] is True, ingestion
        assert set(ingestion["splits"]) == {"left_thigh", "left_shank", "right_thigh", "right_shank"}
        a, b = ingestion["splits"]["right_shank"]["spans_s"]["standing"]
        moved = [round(a + 2.0, 1), round(b - 2.0, 1)]
        r = c.put(f"/api/v1/sessions/{sid}/split", headers=h, json={"split": {"right_shank": {"standing": moved}}})
        assert r.status_code == 200, r.text
        splits = r.json()["splits"]
        assert splits["right_shank"]["how"] == "session.json" and splits["right_shank"]["spans_s"]["standing"] == moved
        assert {k: v["how"] for k, v in splits.items() if k != "right_shank"} == dict.fromkeys(
            ("left_shank", "left_thigh", "right_thigh"), "role")
        r = c.put(f"/api/v1/sessions/{sid}/split", headers=h, json={"split": {"shank": {"standing": moved}}})
        assert r.status_code == 200 and r.json()["ok"] is False  # a plain key cannot say which knee: the check refuses
