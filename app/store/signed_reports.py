"""An analysis' reports with the clinician's signed interpretation (issue 17 §3), rendered when asked for.

The job renders report.pdf and report.html before anyone has read them, so before any interpretation exists; the
interpretation is signed (and maybe amended) later.  When a signed one exists, :func:`render_signed` renders the
report again from the analysis' own stored ``results.json`` and ``timeseries.npz`` (the same numbers, bit for bit:
:func:`app.pipeline.results.report_input_of_files`), the patient's identity as the job had it (the same
``session.json`` facts: :func:`app.store.workspace.build_manifest`, unchanged while the analysis is current, since
correcting them supersedes it) and the interpretation, so the download always shows the interpretation as it
stands now: its text, signer, role and time, and "amended" with each amendment and the text it replaced.  Without a
signed interpretation the stored bytes are served as they are (the caller's fallback).
"""

from __future__ import annotations

import json

from sqlalchemy.orm import Session

from app.pipeline.render import render_artefact
from app.pipeline.results import patient_of, report_input_of_files
from app.store import interpretations
from app.store.analyses import artefact
from app.store.blobs import BlobStore
from app.store.models import Analysis, Clinic, KneeSession
from app.store.workspace import build_manifest, uploaded_manifest

#: the artefacts that print the interpretation
SIGNED_ARTEFACTS = ("report.pdf", "report.html")


def render_signed(db: Session, store: BlobStore, session: KneeSession, analysis: Analysis, name: str, lang: str,
                  identifier_system: str | None) -> bytes | None:
    """``name`` (report.pdf or report.html) of ``analysis`` in ``lang`` with its signed interpretation, or None when
    it has none signed (serve the stored file) or ``name`` does not print one."""
    if name not in SIGNED_ARTEFACTS:
        return None
    signed = interpretations.as_report(interpretations.find(db, analysis.id))
    if signed is None:
        return None
    results = json.loads(store.read(artefact(db, analysis, "results.json").sha256))
    npz = store.read(artefact(db, analysis, "timeseries.npz").sha256)
    clinic = db.get(Clinic, session.clinic_id)
    recordings = list(session.recordings)
    manifest = build_manifest(session, session.patient, recordings, uploaded_manifest(store, recordings),
                              clinic=clinic.name if clinic is not None else "", identifier_system=identifier_system)
    facts = results.get("session") or {}
    recorded = facts.get("recorded") or {}
    patient = patient_of(manifest, record=manifest.get("patient_id"), date=manifest.get("date"),
                         side=str(results.get("side") or session.patient.side or ""),
                         step_height_m=facts.get("step_height_m"),
                         recorded=(recorded.get("first") or "", recorded.get("last") or ""))
    ri = report_input_of_files(results, npz, patient, lang or analysis.lang, signed)
    return render_artefact(ri, name, ri.language)


__all__ = ["SIGNED_ARTEFACTS", "render_signed"]
