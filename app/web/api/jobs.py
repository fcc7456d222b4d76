"""Processing: ``POST /sessions/{id}/process`` queues a job; ``GET /jobs/{id}`` follows it.

The rules are :func:`app.jobs.queue.enqueue`'s (the same for ``chakamo reprocess``): while a job of the
session is queued or running a new request answers 409 (checked before and, for SQLite's concurrent writers,
again after inserting); a stale ingestion check (files changed since) is redone before deciding (409 when it
is not ok).  The job row is committed before the runner hears of it, so a crash between the two loses nothing
(the runner's start-up resubmits queued jobs).  Every analysis is kept: processing again (e.g. with another
filter) adds one.
"""

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from app.choices import DEFAULT_FILTER
from app.jobs.queue import enqueue, hand_over
from app.web import audit
from app.web.api.deps import CheckerDep, Clinician, DbDep, Reader, RunnerDep, scoped_job, scoped_session
from app.web.api.schemas import JobCreatedOut, JobOut, ProcessIn, job_out

router = APIRouter(tags=["jobs"])


@router.post("/sessions/{session_id}/process", response_model=JobCreatedOut, status_code=202,
             responses={409: {"description": "recordings not ready, or the session is being processed"}})
def process(session_id: int, principal: Clinician, db: DbDep, runner: RunnerDep, checker: CheckerDep,
            request: Request, body: ProcessIn | None = None):
    body = body or ProcessIn()
    name = body.filter or DEFAULT_FILTER  # the schema accepts only app.choices.FILTER_NAMES
    job = enqueue(db, principal.clinic_id, session_id, filter_name=name, lang=body.lang, checker=checker,
                  heading=body.heading, side=body.side, involved=body.involved)
    session = scoped_session(db, principal, session_id)  # the row enqueue loaded (no new query)
    audit.record(db, request, principal, "process", patient_id=session.patient_id, session_id=session.id)
    db.commit()  # committed before the runner can look for it
    hand_over(runner, job.id)
    return JSONResponse({"job_id": job.id}, status_code=202)


@router.get("/jobs/{job_id}", response_model=JobOut)
def get_job(job_id: int, principal: Reader, db: DbDep):
    return job_out(scoped_job(db, principal, job_id))
