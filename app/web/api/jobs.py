"""Processing: ``POST /sessions/{id}/process`` queues a job; ``GET /jobs/{id}`` follows it.

The job row is committed before the runner hears of it, so a crash between the two loses nothing (the
runner's start-up resubmits queued jobs).  Every analysis is kept: processing again (e.g. with another
filter) adds one — once the previous job of the session has finished: while one is queued or running a
new request answers 409 (checked before and, for SQLite's concurrent writers, again after inserting).  A
stale ingestion check (files changed since) is redone before deciding (409 when it is not ok).
"""

import logging

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import JSONResponse
from sqlalchemy import select

from app.web import audit
from app.web.api.deps import Clinician, DbDep, Reader, RunnerDep, refuse_while_processing, scoped_job, scoped_session
from app.web.api.recordings import ensure_fresh_ingestion
from app.web.api.schemas import JobCreatedOut, JobOut, ProcessIn, ingestion_fresh, job_out
from app.store.models import Job
from app.pipeline.session import PIPELINE_VERSION
from app.choices import DEFAULT_FILTER

router = APIRouter(tags=["jobs"])
log = logging.getLogger("chakamo.jobs")


@router.post("/sessions/{session_id}/process", response_model=JobCreatedOut, status_code=202,
             responses={409: {"description": "recordings not ready, or the session is being processed"}})
def process(session_id: int, principal: Clinician, db: DbDep, runner: RunnerDep, request: Request,
            body: ProcessIn | None = None):
    body = body or ProcessIn()
    session = scoped_session(db, principal, session_id)
    name = body.filter or DEFAULT_FILTER  # the schema accepts only app.choices.FILTER_NAMES
    refuse_while_processing(db, session.id, "process it again")
    ensure_fresh_ingestion(db, request, session)
    session = scoped_session(db, principal, session_id, lock=True)
    refuse_while_processing(db, session.id, "process it again")
    ingestion = session.ingestion if ingestion_fresh(session) else {}
    if not ingestion.get("ok"):
        raise HTTPException(409, "The session's recordings are not ready to process: "
                                 f"{ingestion.get('error') or 'no recordings yet'}")
    job = Job(clinic_id=principal.clinic_id, session_id=session.id, filter=name, lang=body.lang,
              log=[], stage="queued", pipeline_version=PIPELINE_VERSION)
    db.add(job)
    db.flush()
    other = db.scalar(select(Job.id).where(Job.session_id == session.id, Job.id != job.id,
                                           Job.status.in_(("queued", "running"))))
    if other is not None:  # another request queued one at the same moment (SQLite has no row locks)
        raise HTTPException(409, f"Session {session.id} is being processed (job {other}); process it again when "
                                 "that job has finished.")
    audit.record(db, request, principal, "process", patient_id=session.patient_id, session_id=session.id)
    db.commit()  # committed before the runner can look for it
    try:
        runner.submit(job.id)
    except Exception:  # noqa: BLE001 — the job is committed: the engine's sweeper hands it over later
        log.warning("job %s queued but not handed to the engine now; the sweeper will", job.id, exc_info=True)
    return JSONResponse({"job_id": job.id}, status_code=202)


@router.get("/jobs/{job_id}", response_model=JobOut)
def get_job(job_id: int, principal: Reader, db: DbDep):
    return job_out(scoped_job(db, principal, job_id))
