"""The session.json the server builds from an uploaded one (``app.store.workspace.build_manifest``): an uploaded
manifest of the wrong shape is refused with a sentence naming session.json, never a TypeError."""

from __future__ import annotations

import datetime as dt

import pytest


def _rows():
    from app.store.models import KneeSession, Patient, Recording

    patient = Patient(id=1, clinic_id=1, external_id="W-1", side="left")
    session = KneeSession(id=1, clinic_id=1, patient_id=1, date=dt.date(2026, 12, 1), task="step_up")
    recordings = [Recording(id=1, session_id=1, file_name="standing-muslo.xlsx", size_bytes=1, sha256="0" * 64)]
    return session, patient, recordings


@pytest.mark.parametrize("uploaded", [[1, 2], "text", 3, {"recordings": 3}, {"recordings": {"files": []}}])
def test_a_manifest_of_the_wrong_shape_is_refused_naming_it(uploaded):
    from app.pipeline.ingestion import IngestionError
    from app.store.workspace import build_manifest

    with pytest.raises(IngestionError, match=r"^session\.json: .*fix it or delete that recording"):
        build_manifest(*_rows(), uploaded=uploaded)


def test_a_good_manifest_keeps_its_keys_and_gains_the_sessions_facts():
    from app.store.workspace import build_manifest

    out = build_manifest(*_rows(), uploaded={"recordings": [{"files": ["standing-muslo.xlsx"]}], "note": "x"})
    assert out["note"] == "x" and out["side"] == "left" and out["patient_id"] == "W-1" and out["date"] == "2026-12-01"


def test_an_uploaded_manifest_never_supplies_the_identity_the_database_lacks():
    """The database is the only source of who the report is about: a session.json's name, birth date, sex,
    clinic... are dropped even where the database has none (the patient here has no name, birth date or sex)."""
    from app.store.workspace import IDENTITY_KEYS, build_manifest

    uploaded = {"recordings": [{"files": ["standing-muslo.xlsx"]}], "name": "Someone Else", "birth_date": "1950-01-01",
                "sex": "male", "clinic": "Elsewhere", "identifier_system": "urn:x", "professional": "Dr. X",
                "weight_kg": 90, "height_m": 1.9, "observations": "from the file", "patient_id": "FILE-9"}
    out = build_manifest(*_rows(), uploaded=uploaded)
    assert out["patient_id"] == "W-1"  # the database's
    assert not {k for k in IDENTITY_KEYS if k != "patient_id"} & set(out), out
