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
