"""An analysis' reports with the clinician's signed interpretation (issue 17 §3): rendered once, stored, served.

The job renders report.pdf and report.html before anyone has read them, so before any interpretation exists; the
interpretation is signed (and maybe amended) later.  At the signature and at each amendment (:func:`sign`,
:func:`amend`), :func:`render_signed` renders both reports in every language, from the analysis' own stored ``results.json`` and
``timeseries.npz`` (the same numbers, bit for bit: :func:`app.pipeline.results.report_input_of_files`) and its
``patient.json`` (the identity block the job printed: :func:`app.pipeline.render.patient_json`, so a patient
corrected since — which supersedes the analysis — never changes what this analysis' signed report says), with the
interpretation as it will stand — before the conditional write, so no lock is held while rendering, and the write
checks nothing changed in between (:data:`app.store.interpretations.Prepare`); each file is stored as an artefact of the analysis named
``signed-<version>-report.pdf`` / ``…-report.html`` (version 0 the signature, n the n-th amendment) and its sha256
goes into the sign/amend audit event (:func:`audit_detail`).  Every version stays stored: what was signed, and
every amendment's report, can be shown again byte for byte.

:func:`signed_artefact` is the stored signed file of the interpretation's current version: the downloads
(:mod:`app.web.api.artefacts`) and the FHIR presentedForm (:mod:`app.web.api.fhir`, :mod:`app.web.fhir_push`)
serve it instead of the job's unsigned report; no request renders anything.  An analysis stored before
``patient.json`` existed is rendered with the identity :func:`app.store.workspace.build_manifest` gives from the
database (the only source the web path has for it; an uploaded session.json's identity is never printed).
"""

from __future__ import annotations

import hashlib
import json

from sqlalchemy.orm import Session

from app.pipeline.render import LANGS, MEDIA, render_artefact
from app.pipeline.results import patient_of, report_input_of_files
from app.store import interpretations
from app.store.analyses import artefact, find_artefact
from app.store.blobs import Storage, commit_all, discarding
from app.store.erasure import reserve_blobs
from app.store.models import Analysis, Artefact, Clinic, Interpretation, KneeSession, User
from app.store.workspace import build_manifest
from reports.model import Interpretation as ReportInterpretation
from reports.model import Patient

#: the artefacts that print the interpretation
SIGNED_ARTEFACTS = ("report.pdf", "report.html")
#: the job's identity block of the analysis (:func:`app.pipeline.render.patient_json`)
PATIENT_JSON = "patient.json"


def signed_name(name: str, version: int) -> str:
    """The artefact name of ``name``'s signed rendering ``version`` (0: the signature; n: the n-th amendment)."""
    return f"signed-{version}-{name}"


def analysis_patient(db: Session, store: Storage, session: KneeSession, analysis: Analysis,
                     identifier_system: str | None) -> Patient:
    """The identity block ``analysis``' reports printed: its ``patient.json``; for an analysis stored before that
    file existed, the database's facts (module docstring)."""
    stored = find_artefact(db, analysis.id, PATIENT_JSON)
    if stored is not None:
        return Patient(**json.loads(store.read(stored.sha256)))
    results = json.loads(store.read(artefact(db, analysis, "results.json").sha256))
    clinic = db.get(Clinic, session.clinic_id)
    manifest = build_manifest(session, session.patient, [], None, clinic=clinic.name if clinic is not None else "",
                              identifier_system=identifier_system)
    facts = results.get("session") or {}
    recorded = facts.get("recorded") or {}
    return patient_of(manifest, record=manifest.get("patient_id"), date=manifest.get("date"),
                      side=str(results.get("side") or session.patient.side or ""),
                      step_height_m=facts.get("step_height_m"),
                      recorded=(recorded.get("first") or "", recorded.get("last") or "", recorded.get("zone") or ""))


def render_signed(db: Session, store: Storage, session: KneeSession, analysis: Analysis,
                  signed: ReportInterpretation, identifier_system: str | None) -> dict[tuple[str, str], bytes]:
    """The PDF and HTML of ``analysis`` with ``signed`` in every language, ``{(name, lang): bytes}`` (reads only)."""
    results = json.loads(store.read(artefact(db, analysis, "results.json").sha256))
    npz = store.read(artefact(db, analysis, "timeseries.npz").sha256)
    patient = analysis_patient(db, store, session, analysis, identifier_system)
    files = {}
    for lang in LANGS:
        ri = report_input_of_files(results, npz, patient, lang, signed)
        files.update({(name, lang): render_artefact(ri, name, lang) for name in SIGNED_ARTEFACTS})
    return files


def _store(db: Session, store: Storage, analysis: Analysis, version: int,
           files: dict[tuple[str, str], bytes]) -> dict[tuple[str, str], str]:
    """Each of ``files`` placed under its blob's lock (:func:`app.store.erasure.reserve_blobs`, as a job's) and named
    by an artefact ``signed-<version>-<name>`` of ``analysis``: ``{(name, lang): sha256}``."""
    digests = {key: (hashlib.sha256(data).hexdigest(), len(data)) for key, data in files.items()}
    writers = {}
    with discarding(writers.values()):
        for key, data in files.items():
            writers[key] = store.sealed(data)
        reserve_blobs(db, list(digests.values()))  # all the rows locked first (in sha256 order), as an upload's
        commit_all(list(writers.values()))
    for (name, lang), (sha, size) in digests.items():
        db.add(Artefact(analysis_id=analysis.id, name=signed_name(name, version), lang=lang, media_type=MEDIA[name],
                        sha256=sha, size_bytes=size))
    db.flush()
    return {key: sha for key, (sha, _) in digests.items()}


def sign(db: Session, store: Storage, session: KneeSession, analysis: Analysis, user: User | None, expected: str,
         identifier_system: str | None) -> tuple[Interpretation, dict[tuple[str, str], str]]:
    """:func:`app.store.interpretations.sign` with its reports: rendered before the signature's write (no lock held
    while rendering), stored after it; the row and ``{(name, lang): sha256}``."""
    files: dict[tuple[str, str], bytes] = {}
    row = interpretations.sign(db, session, analysis, user, expected, prepare=lambda signed: files.update(
        render_signed(db, store, session, analysis, signed, identifier_system)))
    return row, _store(db, store, analysis, len(row.amendments), files)


def amend(db: Session, store: Storage, session: KneeSession, analysis: Analysis, user: User | None, text: str,
          reason: str, expected: str | None, identifier_system: str | None
          ) -> tuple[Interpretation, dict[tuple[str, str], str]]:
    """:func:`app.store.interpretations.amend` with its reports, as :func:`sign`."""
    files: dict[tuple[str, str], bytes] = {}
    row = interpretations.amend(db, session, analysis, user, text, reason, expected, prepare=lambda signed: files.update(
        render_signed(db, store, session, analysis, signed, identifier_system)))
    return row, _store(db, store, analysis, len(row.amendments), files)


def audit_detail(analysis: Analysis, row: Interpretation, stored: dict[tuple[str, str], str]) -> str:
    """The sign/amend audit event's detail: the version and the sha256 of the signed PDF and HTML in the analysis'
    language (the other languages' are in their artefact rows)."""
    lang = analysis.lang if (SIGNED_ARTEFACTS[0], analysis.lang) in stored else LANGS[0]
    return (f"interpretation of analysis {analysis.id}, signed report {len(row.amendments)} ({lang}): "
            f"pdf sha256 {stored['report.pdf', lang]}, html sha256 {stored['report.html', lang]}")


def signed_artefact(db: Session, analysis: Analysis, name: str, lang: str) -> Artefact | None:
    """The stored signed ``name`` in ``lang`` of ``analysis``' interpretation as it stands, or None when none is
    signed (serve the job's file) or ``name`` does not print one."""
    if name not in SIGNED_ARTEFACTS:
        return None
    row = interpretations.find(db, analysis.id)
    if row is None or row.signed_at is None:
        return None
    return find_artefact(db, analysis.id, signed_name(name, len(row.amendments)), lang)


__all__ = ["PATIENT_JSON", "SIGNED_ARTEFACTS", "amend", "analysis_patient", "audit_detail", "render_signed", "sign",
           "signed_artefact", "signed_name"]
