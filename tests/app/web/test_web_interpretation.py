"""The clinician's interpretation and sign-off, and the reports' identity through the web job (issue 17 §3).

The demo session (real MetaBase files, recorded on 2026-11-22 by the simulated phones' clock) is uploaded for a
patient with a record number, birth date and sex, in a clinic with a name and a configured identifier system;
the job's PDF (every page, read with poppler's pdftotext), HTML and download names must carry them.  Then a
clinician writes, signs and amends an interpretation: each step audited, the text locked after signing, the
amendment keeping the earlier text, the reports rendered with all of it, other clinics and tokens refused.
"""

from __future__ import annotations

import datetime as dt
import shutil

import pytest

from web_helpers import clinic_token, demo_files, wait_job
from pdf_pages import pdf_pages

PASSWORD = "a long enough password"
SYSTEM = "urn:oid:2.16.724.4.9.20.90"


@pytest.fixture
def settings(tmp_path, database_url):
    from web_helpers import make_settings

    extra = {"DATABASE_URL": database_url} if database_url else {}
    return make_settings(tmp_path / "data", CHAKAMO_PATIENT_IDENTIFIER_SYSTEM=SYSTEM, **extra)


@pytest.fixture(autouse=True)
def _fresh_settings_cache():
    """The job reads CHAKAMO_PATIENT_IDENTIFIER_SYSTEM through the process' settings (app.settings.get_settings)."""
    import os

    from app.settings import get_settings

    old = os.environ.get("CHAKAMO_PATIENT_IDENTIFIER_SYSTEM")
    os.environ["CHAKAMO_PATIENT_IDENTIFIER_SYSTEM"] = SYSTEM
    get_settings.cache_clear()
    yield
    if old is None:
        os.environ.pop("CHAKAMO_PATIENT_IDENTIFIER_SYSTEM", None)
    else:
        os.environ["CHAKAMO_PATIENT_IDENTIFIER_SYSTEM"] = old
    get_settings.cache_clear()




def _login(client, email: str) -> dict:
    r = client.post("/api/v1/auth/login", json={"email": email, "password": PASSWORD})
    assert r.status_code == 200, r.text
    return {"X-CSRF-Token": r.json()["csrf_token"]}


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext not installed")
def test_identity_sign_off_and_amendment(client, settings, demo_dir):
    from app.cli import admin as admin_cli
    from reports.i18n import t

    token = clinic_token(settings, "Hospital Norte")
    admin_cli.create_user(settings, clinic="Hospital Norte", email="laura@norte.test", role="clinician",
                          password=PASSWORD, name="Dra. Laura Pérez")
    admin_cli.create_user(settings, clinic="Hospital Norte", email="ro@norte.test", role="read_only",
                          password=PASSWORD, name="Lector")
    other = clinic_token(settings, "Clínica Sur")

    r = client.post("/api/v1/patients", json={"external_id": "HC-0042", "side": "right", "name": "Ana Sánchez",
                                               "birth_date": "1960-11-23", "sex": "female"}, headers=token)
    assert r.status_code == 201, r.text
    pid = r.json()["id"]
    r = client.post(f"/api/v1/patients/{pid}/sessions", json={"step_height_m": 0.17, "date": "2026-12-01"},
                    headers=token)
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir),
                       headers=token).status_code in (200, 201)
    job = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={"lang": "es"},
                                       headers=token).json()["job_id"], token)
    assert job["status"] == "done", job

    # identity on every page, the recordings' date (the phones' clock), not the session's
    r = client.get(f"/api/v1/sessions/{sid}/report.pdf", params={"lang": "en"}, headers=token)
    assert r.status_code == 200
    assert 'filename="chakamo-HC-0042-2026-11-22-s' in r.headers["content-disposition"]
    assert r.headers["content-disposition"].endswith('-en-report.pdf"')
    pages = pdf_pages(r.content)
    for text in pages:
        for part in (f"Record no.: HC-0042 ({SYSTEM})", "Born: 1960-11-23 (age 65)", "Sex: female",
                     "Clinic: Hospital Norte", "Recorded on: 2026-11-22", "Ana Sánchez"):
            assert part in text, part
    # the HTML report in every language, named alike
    for lang in ("es", "en", "pt"):
        r = client.get(f"/api/v1/sessions/{sid}/report.html", params={"lang": lang}, headers=token)
        assert r.status_code == 200 and f'<html lang="{lang}"' in r.text
        assert f"-{lang}-report.html" in r.headers["content-disposition"]
        assert t("id.clinic", lang) in r.text and "HC-0042" in r.text
    r = client.get(f"/api/v1/sessions/{sid}/angles.xlsx", headers=token)
    assert 'filename="chakamo-HC-0042-2026-11-22-s' in r.headers["content-disposition"]

    # nothing yet; another clinic cannot see or write it
    assert client.get(f"/api/v1/sessions/{sid}/interpretation", headers=token).json()["status"] == "none"
    assert client.get(f"/api/v1/sessions/{sid}/interpretation", headers=other).status_code == 404
    assert client.post(f"/api/v1/sessions/{sid}/interpretation", json={"text": "x"}, headers=other).status_code == 404

    text = "Flexión máxima reducida respecto a la referencia; revisar en 6 semanas."
    r = client.post(f"/api/v1/sessions/{sid}/interpretation", json={"text": text}, headers=token)
    assert r.status_code == 200 and r.json()["status"] == "draft", r.text
    unsigned_pdf = client.get(f"/api/v1/sessions/{sid}/report.pdf", headers=token).content
    # an API token cannot sign: a signature names a person
    r = client.post(f"/api/v1/sessions/{sid}/interpretation/sign", json={"text": text}, headers=token)
    assert r.status_code == 400, r.text

    # a read-only user cannot sign
    ro = _login(client, "ro@norte.test")
    assert client.post(f"/api/v1/sessions/{sid}/interpretation/sign", json={"text": text},
                       headers=ro).status_code == 403
    client.post("/api/v1/auth/logout", headers=ro)

    csrf = _login(client, "laura@norte.test")
    # the signer names the text they read: another text saved meanwhile (here by the token) is not signed unseen
    assert client.post(f"/api/v1/sessions/{sid}/interpretation", json={"text": text + " (token)"},
                       headers=token).status_code == 200
    r = client.post(f"/api/v1/sessions/{sid}/interpretation/sign", json={"text": text}, headers=csrf)
    assert r.status_code == 409 and r.headers["X-ChakaMo-Code"] == "store.interpretation_changed", r.text
    assert client.get(f"/api/v1/sessions/{sid}/interpretation", headers=token).json()["status"] == "draft"
    assert client.post(f"/api/v1/sessions/{sid}/interpretation/sign", headers=csrf).status_code == 422  # no text
    assert client.post(f"/api/v1/sessions/{sid}/interpretation", json={"text": text},
                       headers=csrf).status_code == 200
    before = dt.datetime.now(dt.timezone.utc).replace(microsecond=0)
    r = client.post(f"/api/v1/sessions/{sid}/interpretation/sign", json={"text": text}, headers=csrf)
    assert r.status_code == 200, r.text
    signed = r.json()
    assert signed["status"] == "signed" and signed["signed_by"] == "Dra. Laura Pérez"
    assert signed["signed_role"] == "clinician"
    assert dt.datetime.fromisoformat(signed["signed_at"]) >= before
    # locked: a second signature and a draft save are refused
    assert client.post(f"/api/v1/sessions/{sid}/interpretation/sign", json={"text": text},
                       headers=csrf).status_code == 409
    assert client.post(f"/api/v1/sessions/{sid}/interpretation", json={"text": "otra"},
                       headers=csrf).status_code == 409
    # the signed report is rendered once and stored: the same bytes at every download, not the job's file
    signed_pdf = client.get(f"/api/v1/sessions/{sid}/report.pdf", headers=csrf).content
    assert signed_pdf != unsigned_pdf
    assert client.get(f"/api/v1/sessions/{sid}/report.pdf", headers=csrf).content == signed_pdf
    # an amendment must name the signed text it replaces when it says one: another is refused
    r = client.post(f"/api/v1/sessions/{sid}/interpretation/amendments",
                    json={"text": "nuevo", "reason": "r", "expected_text": "otro texto"}, headers=csrf)
    assert r.status_code == 409, r.text
    # an amendment needs a reason, and keeps the earlier text
    assert client.post(f"/api/v1/sessions/{sid}/interpretation/amendments", json={"text": "nuevo", "reason": ""},
                       headers=csrf).status_code == 422
    new = "Flexión máxima reducida; revisar en 4 semanas."
    r = client.post(f"/api/v1/sessions/{sid}/interpretation/amendments",
                    json={"text": new, "reason": "plazo corregido", "expected_text": text}, headers=csrf)
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["text"] == new and body["amended"] and body["amendments"][0]["previous_text"] == text
    assert body["amendments"][0]["by"] == "Dra. Laura Pérez" and body["amendments"][0]["reason"] == "plazo corregido"

    # the reports print it: text, signer, "amended", the history with the earlier text
    for lang in ("es", "pt"):
        r = client.get(f"/api/v1/sessions/{sid}/report.pdf", params={"lang": lang}, headers=csrf)
        words = " ".join(pdf_pages(r.content))
        for part in (t("interp.section", lang), new, "Dra. Laura Pérez", t("interp.amended", lang), text,
                     "plazo corregido", t("id.clinic", lang) + ": Hospital Norte"):
            assert part in words, (lang, part)
    r = client.get(f"/api/v1/sessions/{sid}/report.html", params={"lang": "en"}, headers=csrf)
    assert new in r.text and "plazo corregido" in r.text and t("interp.amended", "en") in r.text
    # the amended text is not printed under the first signer alone: first signed, last amended, with the reason
    words = " ".join(pdf_pages(client.get(f"/api/v1/sessions/{sid}/report.pdf", params={"lang": "en"},
                                           headers=csrf).content))
    assert "First signed by Dra. Laura Pérez (clinician) on" in words
    assert "last amended by Dra. Laura Pérez (clinician) on" in words and "UTC (plazo corregido)" in words
    assert "First signed by" in r.text and "last amended by" in r.text
    amended_pdf = client.get(f"/api/v1/sessions/{sid}/report.pdf", headers=csrf).content
    assert amended_pdf != signed_pdf
    # the FHIR DiagnosticReport carries the signed (amended) PDF, not the job's unsigned one
    import base64

    doc = client.get(f"/api/v1/fhir/DiagnosticReport/{sid}", headers=token).json()
    report = doc if doc.get("resourceType") == "DiagnosticReport" else next(
        e["resource"] for e in doc["entry"] if e["resource"]["resourceType"] == "DiagnosticReport")
    assert base64.b64decode(report["presentedForm"][0]["data"]) == amended_pdf

    # audited: sign and amend, by the user
    events = client.get("/api/v1/audit", params={"session_id": sid}, headers=clinic_token(settings, "Hospital Norte",
                                                                                        role="admin")).json()
    items = events["items"] if isinstance(events, dict) else events
    actions = [(e["action"], e["actor"]) for e in items]
    assert ("sign", "laura@norte.test") in actions and ("amend", "laura@norte.test") in actions
    assert any(a == "update" for a, _ in actions)
    # the audit names what was signed: the sha256 of the stored signed PDF (the job's language, es)
    import hashlib

    details = {e["action"]: e.get("detail", "") for e in items if e["action"] in ("sign", "amend")}
    assert hashlib.sha256(signed_pdf).hexdigest() in details["sign"], details
    assert hashlib.sha256(amended_pdf).hexdigest() in details["amend"], details

    # a corrected printed fact supersedes the analysis: its interpretation can no longer be signed or amended
    r = client.patch(f"/api/v1/patients/{pid}", json={"sex": "other"}, headers=token)
    assert r.status_code == 200, r.text
    r = client.post(f"/api/v1/sessions/{sid}/interpretation/amendments",
                    json={"text": "otra", "reason": "x", "analysis_id": job["analysis_id"]}, headers=csrf)
    assert r.status_code == 409, r.text
    kept = client.get(f"/api/v1/sessions/{sid}/interpretation", params={"analysis_id": job["analysis_id"]},
                      headers=token).json()
    assert kept["status"] == "signed" and kept["text"] == new  # kept, for the record
    # and its signed report is the one stored: the identity the job printed (female), never the corrected one
    r = client.get(f"/api/v1/sessions/{sid}/report.pdf", params={"analysis_id": job["analysis_id"], "lang": "en"},
                   headers=token)
    assert r.status_code == 200
    words = " ".join(pdf_pages(r.content))
    assert "Sex: female" in words and "Sex: other" not in words
    assert client.get(f"/api/v1/sessions/{sid}/report.pdf", params={"analysis_id": job["analysis_id"]},
                      headers=token).content == amended_pdf

    # erasing the session erases the interpretation and its history with it
    admin = clinic_token(settings, "Hospital Norte", role="admin")
    version = client.get(f"/api/v1/sessions/{sid}", headers=admin).headers["ETag"]
    assert client.delete(f"/api/v1/sessions/{sid}", headers=admin | {"If-Match": version}).status_code == 204
    from sqlalchemy import func, select

    from app.store.models import Interpretation, InterpretationAmendment

    with client.app.state.db.session() as s:
        assert s.scalar(select(func.count()).select_from(Interpretation)) == 0
        assert s.scalar(select(func.count()).select_from(InterpretationAmendment)) == 0
