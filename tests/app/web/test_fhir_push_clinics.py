"""The FHIR push reaches only the clinics the operator opted in, follows the operator's URL, and refuses to match
two clinics' record numbers in one namespace (second review of issue 17 §2).

A real database (SQLite and PostgreSQL) migrated by the product; the settings as the server reads them.
"""

from __future__ import annotations

import datetime as dt

import pytest
from web_helpers import make_settings

from app.store import webhooks
from app.store.database import Database
from app.store.models import Clinic, WebhookDelivery, WebhookSubscription, utcnow

URL = "https://fhir.hospital.example/fhir"


@pytest.fixture
def db(tmp_path, database_url):
    database = Database(database_url or f"sqlite:///{tmp_path / 'push.db'}")
    database.migrate()
    with database.session() as s:
        s.add_all([Clinic(name="Hospital A"), Clinic(name="Clínica B")])
        s.commit()
    yield database
    database.dispose()


def _push(db) -> dict[str, tuple[str, str]]:
    """Each clinic's FHIR push subscription: ``name -> (url, events)``."""
    with db.session() as s:
        return {name: (url, events) for name, url, events in s.execute(
            WebhookSubscription.__table__.select().with_only_columns(Clinic.name, WebhookSubscription.url,
                                                                     WebhookSubscription.events)
            .join_from(WebhookSubscription, Clinic, Clinic.id == WebhookSubscription.clinic_id)
            .where(WebhookSubscription.kind == "fhir"))}


def test_only_the_clinics_opted_in_are_pushed_and_the_operators_url_is_followed(db):
    with db.session() as s:
        assert webhooks.ensure_fhir_push(s, URL, ("Hospital A", "Hospital Z")) == ("Hospital Z",)
    assert _push(db) == {"Hospital A": (URL, "job.done")}  # every clinic was subscribed before: no opt-in
    with db.session() as s:
        sub = s.query(WebhookSubscription).filter_by(kind="fhir").one()
        s.add(WebhookDelivery(subscription_id=sub.id, clinic_id=sub.clinic_id, job_id=1, event="job.done",
                              payload={"event": "job.done"}, state="pending", attempts=0,
                              next_attempt_at=utcnow() - dt.timedelta(seconds=1), last_error=""))
        s.commit()
        first = sub.created_at

    moved = "https://fhir2.hospital.example/r4"
    with db.session() as s:  # the operator moved the server: the stored URL follows (it stayed the old one)
        webhooks.ensure_fhir_push(s, moved, ("Hospital A",))
    assert _push(db) == {"Hospital A": (moved, "job.done")}

    with db.session() as s:  # opted out: nothing more is claimed, the trail stays
        webhooks.ensure_fhir_push(s, moved, ("Clínica B",))
        assert webhooks.claim_due(s, kinds=("fhir",)) is None
        assert s.query(WebhookDelivery).count() == 1
    assert _push(db) == {"Hospital A": (moved, ""), "Clínica B": (moved, "job.done")}

    with db.session() as s:  # opted in again: afresh (a job that ended while it was out is not pushed)
        webhooks.ensure_fhir_push(s, moved, ("Hospital A", "Clínica B"))
        due = webhooks.claim_due(s, kinds=("fhir",))
        assert due is not None and due.url == moved
        assert s.query(WebhookSubscription).filter_by(kind="fhir", events="job.done").count() == 2
        again = s.query(WebhookSubscription).filter_by(kind="fhir", url=moved).order_by(WebhookSubscription.id).first()
        assert again.created_at > first


def test_the_push_refuses_clinics_that_would_share_one_record_number_namespace(tmp_path):
    from app.settings import SettingsError
    from app.web.fhir_push import FhirPush

    common = {"CHAKAMO_FHIR_PUSH_URL": URL, "CHAKAMO_PUBLIC_URL": "https://chakamo.hospital.example",
              "CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS": "fhir.hospital.example"}
    with pytest.raises(SettingsError, match="CHAKAMO_FHIR_PUSH_CLINICS names no clinic"):
        FhirPush(make_settings(tmp_path, **common), None)
    with pytest.raises(SettingsError, match="one Patient"):
        FhirPush(make_settings(tmp_path, CHAKAMO_FHIR_PUSH_CLINICS="Hospital A, Clínica B",
                               CHAKAMO_PATIENT_IDENTIFIER_SYSTEM="urn:oid:2.16.724.4.9.10.2", **common), None)
    one = FhirPush(make_settings(tmp_path, CHAKAMO_FHIR_PUSH_CLINICS="Hospital A",
                                 CHAKAMO_PATIENT_IDENTIFIER_SYSTEM="urn:oid:2.16.724.4.9.10.2", **common), None)
    assert one.clinics == ("Hospital A",)
    # without the hospital's namespace each patient is matched by ChakaMo's own id, unique across clinics
    two = FhirPush(make_settings(tmp_path, CHAKAMO_FHIR_PUSH_CLINICS="Hospital A, Clínica B,Hospital A", **common), None)
    assert two.clinics == ("Hospital A", "Clínica B")


def test_a_retraction_names_the_job_whose_report_it_retracts(db):
    """A superseded report's retraction is one more delivery of the same subscription and job, told apart by its
    event (migration 0017): its row names the job itself (it held the job's id negated before), once per report."""
    from app.store.analyses import supersede
    from app.store.models import Analysis, Job
    from app.store.patients import add_patient
    from app.store.sessions import add_session

    with db.session() as s:
        webhooks.ensure_fhir_push(s, URL, ("Hospital A",))
        sub = s.query(WebhookSubscription).filter_by(kind="fhir").one()
        pid = add_patient(s, sub.clinic_id, {"external_id": "MRN-1", "side": "right"}).id
        sid = add_session(s, sub.clinic_id, pid, {}).id
        job = Job(clinic_id=sub.clinic_id, session_id=sid, status="done", filter="chakamo", finished_at=utcnow())
        s.add(job)
        s.flush()
        analysis = Analysis(session_id=sid, job_id=job.id, filter="chakamo")
        s.add(analysis)
        s.flush()
        job.analysis_id, job_id = analysis.id, job.id
        s.commit()
        assert webhooks.plan_deliveries(s, kinds=("fhir",)) == 1
        pushed = s.query(WebhookDelivery).one()
        pushed.state = "delivered"
        s.commit()
        assert webhooks.plan_deliveries(s, kinds=("fhir",)) == 0  # not superseded: nothing to retract

        assert supersede(s, [sid]) == 1
        s.commit()
        assert webhooks.plan_deliveries(s, kinds=("fhir",)) == 1
        retraction = s.query(WebhookDelivery).filter_by(event=webhooks.RETRACTION).one()
        assert retraction.job_id == job_id == pushed.job_id and retraction.payload["job"]["id"] == job_id
        assert webhooks.plan_deliveries(s, kinds=("fhir",)) == 0  # one retraction per report
        assert s.query(WebhookDelivery).count() == 2
