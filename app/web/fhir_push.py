"""The push of finished reports to a hospital's FHIR R4 server, as one transaction Bundle per analysis.

When ``CHAKAMO_FHIR_PUSH_URL`` is set, every job that ends ``done`` in a clinic the operator opted in
(``CHAKAMO_FHIR_PUSH_CLINICS``: no clinic's reports leave without that) is pushed: the webhook machinery plans,
claims, retries with back-off and records it (:mod:`app.store.webhooks`: a subscription of kind ``fhir`` per
opted-in clinic; :class:`app.web.webhooks.WebhookSender` hands its deliveries to :meth:`FhirPush.send`), so a push gets the
webhooks' lease, total deadline, SSRF rules (its host must match ``CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS``; an internal
address only when named exactly there), back-off and trail (``GET /fhir/pushes``, codes in es/en/pt).  Each push
delivered is also an ``export`` event in the audit log (actor ``FHIR push``).

The request is ``POST <base>`` with ``Content-Type: application/fhir+json``, ``Authorization: Bearer
<CHAKAMO_FHIR_PUSH_TOKEN>`` and a ``transaction`` Bundle (FHIR R4 §3.1.0.11 "Transaction Processing Rules") built
from the analysis' DiagnosticReport (:func:`app.web.fhir.diagnostic_report`, the same document
``GET /fhir/DiagnosticReport/{id}`` answers) by :func:`transaction_bundle`:

- **Patient**: with ``CHAKAMO_FHIR_PATIENT=reference`` and a patient who has a ``fhir_reference``, no entry:
  every ``subject`` is that reference (the hospital owns the Patient).  With ``identifier`` (or ``reference`` for a
  patient without one) no entry either: ``subject`` is the conditional reference ``Patient?identifier=<system>|<record
  number>`` (§3.1.0.11.2), which the server resolves to the one Patient it has, and a record number it does not know
  (mistyped) fails the transaction instead of making a ghost Patient on a server that owns its Patients.  Only with
  ``contained`` (ChakaMo holds the patient's data: the operator's choice to have patients created) a conditional
  create (``POST Patient`` with ``ifNoneExist: identifier=<system>|<value>``, the hospital's record number when its
  system is configured, else ChakaMo's ``<base>/patients`` id): the server links to the Patient it has, or makes one.
  System and value are escaped as FHIR search values (:func:`_escaped`: ``A,B`` would search for A or B).
- **Observations and DiagnosticReport**: ``POST`` with ``ifNoneExist`` on an identifier of the analysis
  (``<base>/analyses`` | ``<analysis id>`` for the report, ``<analysis id>-<observation>`` for each observation),
  so a retry after a lost answer creates nothing twice, while a new analysis of the session is a new report.
- **Superseded**: a pushed report whose analysis is superseded since (a recording deleted, a printed fact corrected)
  is retracted by one more delivery (:func:`retraction_bundle`): the same resources ``entered-in-error``, each a
  conditional update (``PUT DiagnosticReport?identifier=<base>/analyses|<id>``) of what the first push made.
- **References**: each entry's ``fullUrl`` is a ``urn:uuid:`` (RFC 4122 name-based, version 5, from the analysis
  and the resource: a retry sends the same bundle), and ``subject`` and ``result`` point to those; the server
  replaces them with the ids it assigns (§3.1.0.11.2).

**One record-number namespace, one clinic.**  With ``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM`` set, the server finds
(or, contained, makes) the Patient by ``<system>|<record number>``; two clinics (tenants) pushing in that one
namespace would file clinic A's MRN-42 and clinic B's MRN-42 under one hospital Patient.  There is one system per
server, not per clinic, so the push refuses to start (:class:`app.settings.SettingsError`) with that system set and
more than one clinic opted in: a second clinic needs a server of its own (its own settings), or the push without
the hospital's namespace (then each patient is matched by ChakaMo's own ``<base>/patients`` id, unique across
clinics).  Chosen over a per-clinic system because the settings name one; refusing is the failure that cannot
mix two patients' reports.

An analysis that cannot be exported (superseded since, stored data FHIR cannot express, or a stored file missing or
altered) fails its delivery at once (``fhir.not_exportable``), without retries.  The POST's deadline is what the
delivery's lease has left after the bundle was built (:func:`app.web.webhooks.time_left`).  The bundle is validated with both FHIR model packages before it is
sent (:func:`app.web.fhir.validate_bundle`).
"""

from __future__ import annotations

import json
import logging
import urllib.parse
import uuid
from typing import Any

from sqlalchemy.orm import Session

from app.settings import Settings, SettingsError
from app.store import webhooks
from app.store.analyses import artefact
from app.store.signed_reports import signed_artefact
from app.store.database import Database
from app.store.models import Analysis, KneeSession
from app.web import audit
from app.web.api.schemas import patient_out
from app.web.fhir import CODE_SYSTEM, FhirExportError, diagnostic_report, validate_bundle
from app.web.headers import host_allowed
from app.web.outbound import DEADLINE_S, header_host, plain_host
from app.web.webhooks import attempt

log = logging.getLogger("chakamo.fhir_push")
#: the trail's code of an analysis that cannot be pushed (rendered in es/en/pt, :mod:`app.web.messages`)
NOT_EXPORTABLE = "fhir.not_exportable"
#: the export refusals a clinic can mend, as the push trail's sentences (``app.web.messages``: what to correct, then
#: process again); any other refusal of the export is :data:`NOT_EXPORTABLE` there (the operator's log says which)
TRAIL_CODES = {"fhir.bad_patient_reference": "fhir.patient_reference_invalid",
               "fhir.no_patient_identifier": "fhir.patient_unreferenced"}


def report_inputs(db: Session, store, session: KneeSession, analysis: Analysis) -> dict[str, Any]:
    """The keyword arguments of :func:`app.web.fhir.diagnostic_report` that come from the stored session, its
    patient and the analysis' ``results.json`` and PDF (in the analysis' language): the signed one stored at the
    signature or last amendment when the interpretation is signed (:func:`app.store.signed_reports.signed_artefact`),
    else the job's."""
    results = json.loads(store.read(artefact(db, analysis, "results.json").sha256))
    pdf_row = signed_artefact(db, analysis, "report.pdf", analysis.lang) or artefact(db, analysis, "report.pdf",
                                                                                      analysis.lang)
    pdf = store.read(pdf_row.sha256)
    sess = {"id": session.id, "patient_id": session.patient_id, "date": session.date.isoformat(),
            "task": session.task, "step_height_m": session.step_height_m, "professional": session.professional,
            "notes": session.notes, "created_at": session.created_at.isoformat(), "analysis_id": analysis.id,
            "analysis_created_at": analysis.created_at.isoformat(), "filter": analysis.filter,
            "service_request": session.service_request, "encounter": session.encounter,
            "accession": session.accession}
    patient = {k: (v.isoformat() if hasattr(v, "isoformat") else v) for k, v in patient_out(session.patient).items()}
    return {"session": sess, "patient": patient, "results": results, "pdf": pdf, "lang": analysis.lang}


def export_options(settings: Settings) -> dict[str, Any]:
    """The settings-given keyword arguments of :func:`app.web.fhir.diagnostic_report`."""
    return {"patient_identifier_system": settings.patient_identifier_system,
            "code_system": settings.fhir_code_system or CODE_SYSTEM, "patient_mode": settings.fhir_patient,
            "accession_system": settings.accession_system}


def _urn(base_url: str, analysis_id: int, name: str) -> str:
    return f"urn:uuid:{uuid.uuid5(uuid.NAMESPACE_URL, f'{base_url}/analyses/{analysis_id}/{name}')}"


def _escaped(text: str) -> str:
    """``text`` as a search parameter's value (FHIR R4 §3.1.1.5.11 "Escaping Search Parameters"): ``\\``, ``,``
    (which separates alternatives: ``A,B`` means A or B), ``$`` and ``|`` preceded by a backslash."""
    for c in "\\,$|":
        text = text.replace(c, "\\" + c)
    return text


def _conditional(identifier: dict) -> str:
    """The search ``identifier=<system>|<value>`` of ``identifier`` (both escaped: :func:`_escaped`), URL-encoded."""
    token = f"{_escaped(identifier.get('system') or '')}|{_escaped(identifier['value'])}"
    return "identifier=" + urllib.parse.quote(token, safe="/:")


def transaction_bundle(report: dict, *, base_url: str, analysis_id: int) -> dict:
    """The transaction Bundle of one DiagnosticReport of :func:`app.web.fhir.diagnostic_report` (module
    docstring), validated with both model packages.  ``base_url``: the namespace of ChakaMo's identifiers (the
    report's own); ``analysis_id``: the analysis it shows (its identifier makes the creates conditional)."""
    report = json.loads(json.dumps(report))  # a deep copy: the caller's document is left as it was
    contained = {r["id"]: r for r in report.pop("contained", [])}
    analyses = f"{base_url.rstrip('/')}/analyses"
    entries: list[dict] = []
    subject = report["subject"]
    if "patient" in contained:  # ChakaMo holds the patient's data: created unless the server has them already
        patient = contained.pop("patient")
        patient.pop("id", None)
        key = next((i for i in patient["identifier"] if i.get("system")), patient["identifier"][0])
        subject = {"reference": _urn(base_url, analysis_id, "patient"), "type": "Patient"}
        entries.append({"fullUrl": subject["reference"], "resource": patient,
                        "request": {"method": "POST", "url": "Patient", "ifNoneExist": _conditional(key)}})
    elif "identifier" in subject:  # the hospital's Patient, found by its record number; never made up
        subject = {"reference": "Patient?" + _conditional(subject["identifier"]), "type": "Patient"}
    urns = {}
    for local_id, obs in contained.items():
        obs.pop("id", None)
        obs["subject"] = subject
        ident = {"system": analyses, "value": f"{analysis_id}-{local_id}"}
        obs["identifier"] = [ident]
        urns[f"#{local_id}"] = _urn(base_url, analysis_id, local_id)
        entries.append({"fullUrl": urns[f"#{local_id}"], "resource": obs,
                        "request": {"method": "POST", "url": "Observation", "ifNoneExist": _conditional(ident)}})
    report.pop("id", None)
    report["subject"] = subject
    for r in report.get("result", []):
        r["reference"] = urns[r["reference"]]
    ident = {"system": analyses, "value": str(analysis_id)}
    report["identifier"] = [*report.get("identifier", []), ident]
    entries.append({"fullUrl": _urn(base_url, analysis_id, "report"), "resource": report,
                    "request": {"method": "POST", "url": "DiagnosticReport", "ifNoneExist": _conditional(ident)}})
    bundle = {"resourceType": "Bundle", "type": "transaction", "entry": entries}
    validate_bundle(bundle)
    return bundle


def retraction_bundle(bundle: dict) -> dict:
    """The transaction retracting a pushed report (:data:`app.store.webhooks.RETRACTION`): ``bundle``, the report
    as it was pushed (:func:`transaction_bundle`), with its DiagnosticReport and Observations ``entered-in-error``
    (FHIR R4 DiagnosticReport.status, Observation.status: "the report was withdrawn") and each sent as a conditional
    update on its analysis identifier (``PUT DiagnosticReport?identifier=<base>/analyses|<id>``, §3.1.0.5.5: the
    one resource the first push made is replaced); the patient's entry as it was (it finds the same Patient)."""
    out = json.loads(json.dumps(bundle))
    for entry in out["entry"]:
        resource = entry["resource"]
        if resource["resourceType"] in ("DiagnosticReport", "Observation"):
            resource["status"] = "entered-in-error"
            entry["request"] = {"method": "PUT", "url": f"{resource['resourceType']}?{entry['request']['ifNoneExist']}"}
    validate_bundle(out)
    return out


def identifier_base(settings: Settings) -> str | None:
    """The namespace of the pushed identifiers: ``CHAKAMO_FHIR_IDENTIFIER_BASE``, else ``CHAKAMO_PUBLIC_URL``/api/v1
    (as the export route's, but with no request to fall back on); None when neither is set."""
    if settings.fhir_identifier_base:
        return settings.fhir_identifier_base.rstrip("/")
    return settings.public_url + "/api/v1" if settings.public_url else None


class FhirPush:
    """The push of one server (module docstring): :meth:`send` one claimed delivery of kind ``fhir``."""

    def __init__(self, settings: Settings, store) -> None:
        """Refuses (:class:`app.settings.SettingsError`) a push URL whose host ``CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS``
        does not list, without a namespace for the identifiers, with no clinic opted in, or with several clinics
        sharing the hospital's record-number namespace (module docstring)."""
        self.url, self.token, self.store = settings.fhir_push_url, settings.fhir_push_token, store
        self.patterns = settings.fhir_push_host_patterns
        self.clinics = settings.fhir_push_clinic_names
        if not self.clinics:
            raise SettingsError("CHAKAMO_FHIR_PUSH_URL is set but CHAKAMO_FHIR_PUSH_CLINICS names no clinic; list the "
                                "names of the clinics whose reports may be pushed (comma-separated)")
        if len(self.clinics) > 1 and settings.patient_identifier_system:
            raise SettingsError(f"CHAKAMO_FHIR_PUSH_CLINICS names {len(self.clinics)} clinics, but their patients "
                                "would be matched on the FHIR server by record number in the one namespace "
                                "CHAKAMO_PATIENT_IDENTIFIER_SYSTEM, so the same number in two clinics would become one "
                                "Patient; opt in one clinic per server, or unset CHAKAMO_PATIENT_IDENTIFIER_SYSTEM")
        host = urllib.parse.urlsplit(self.url or "").hostname or ""
        if not plain_host(host):
            raise SettingsError(f"CHAKAMO_FHIR_PUSH_URL names the host {host!r}, which is not a host name or an IP "
                                "address")
        if not host_allowed(header_host(host), self.patterns):
            raise SettingsError(f"CHAKAMO_FHIR_PUSH_URL names the host {host!r}, which CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS "
                                "does not list; add it there (exactly, if it is an internal address)")
        self.base_url = identifier_base(settings)
        if self.base_url is None:
            raise SettingsError("CHAKAMO_FHIR_PUSH_URL needs CHAKAMO_PUBLIC_URL or CHAKAMO_FHIR_IDENTIFIER_BASE: the "
                                "pushed identifiers' namespace")
        self.options = export_options(settings)

    def bundle(self, db: Session, due: webhooks.Due) -> tuple[dict, KneeSession] | str:
        """The transaction Bundle of ``due``'s analysis and its session (its :func:`retraction_bundle` for a
        :data:`app.store.webhooks.RETRACTION`); the trail's code when it cannot be exported (superseded, for a
        report to push: :data:`NOT_EXPORTABLE`; else the export's own code when it has one)."""
        job = due.payload["job"]
        retract = due.event == webhooks.RETRACTION
        session = db.get(KneeSession, job["session_id"])
        analysis = db.get(Analysis, job["analysis_id"]) if job.get("analysis_id") else None
        if session is None or analysis is None or (analysis.superseded_at is not None) != retract:
            return NOT_EXPORTABLE
        try:
            # issued: the analysis' time, so that every retry sends the same bundle
            report = diagnostic_report(**report_inputs(db, self.store, session, analysis), base_url=self.base_url,
                                       issued=analysis.created_at.replace(microsecond=0), **self.options)
            bundle = transaction_bundle(report, base_url=self.base_url, analysis_id=analysis.id)
            return (retraction_bundle(bundle) if retract else bundle), session
        except (FhirExportError, LookupError, OSError, ValueError) as exc:  # OSError: a blob missing or altered
            log.warning("FHIR push %s: analysis %s cannot be exported: %s: %s", due.id, analysis.id,
                        type(exc).__name__, exc)  # (CorruptBlob), ValueError: its results.json no longer JSON
            return TRAIL_CODES.get(getattr(exc, "code", None), NOT_EXPORTABLE)

    def send(self, db: Database, due: webhooks.Due, deadline_s: float = DEADLINE_S) -> tuple[int | None, str, bool]:
        """Push ``due`` (``(status or None, the trail's code or "", give up)``); a delivered push is audited.  An
        analysis that cannot be exported gives up at once (:meth:`bundle`); any other failure to build the bundle is
        a failed attempt, retried like one (it escaped the sender's round before: never recorded, the delivery
        claimed again every lease)."""
        try:
            with db.session() as s:
                built = self.bundle(s, due)
                if isinstance(built, str):
                    return None, built, True
                bundle, session = built
                patient_id, session_id = session.patient_id, session.id
        except Exception:  # noqa: BLE001 — the database away, say: an attempt that failed, counted
            log.warning("FHIR push %s: its bundle could not be built", due.id, exc_info=True)
            return None, NOT_EXPORTABLE, False
        headers = {"Content-Type": "application/fhir+json", "Accept": "application/fhir+json",
                   "User-Agent": "ChakaMo-FHIR-push", "X-Request-Id": f"chakamo-delivery-{due.id}"}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        body = json.dumps(bundle, ensure_ascii=False, separators=(",", ":")).encode()
        status, code = attempt(due, self.url, body, headers, self.patterns, deadline_s)
        if not code:
            with db.session() as s:
                audit.record_operator(s, clinic_id=due.clinic_id, action="export", actor="FHIR push",
                                      resource=f"POST {urllib.parse.urlsplit(self.url).hostname}",
                                      detail=f"analysis {due.payload['job']['analysis_id']}"
                                             f"{' retracted' if due.event == webhooks.RETRACTION else ''}, delivery "
                                             f"{due.id}, HTTP {status}", patient_id=patient_id, session_id=session_id)
        return status, code, False


__all__ = ["NOT_EXPORTABLE", "FhirPush", "export_options", "identifier_base", "report_inputs", "retraction_bundle",
           "transaction_bundle"]
