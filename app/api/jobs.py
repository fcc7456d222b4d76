"""Processing: ``POST /sessions/{id}/process`` queues a job; ``GET /jobs/{id}`` follows it.

The job row is committed before the runner hears of it, so a crash between the two loses nothing (the
runner's start-up resubmits queued jobs).  Every analysis is kept: processing again (e.g. with another
filter) adds one.
"""

from fastapi import APIRouter, HTTPException
from fastapi.responses import JSONResponse

from app.api.deps import Clinician, DbDep, Reader, RunnerDep, scoped_job, scoped_session
from app.api.schemas import JobCreatedOut, JobOut, ProcessIn, job_out
from app.db.models import Job
from estimators.orientation import DEFAULT_METHOD, METHODS

router = APIRouter(tags=["jobs"])


@router.post("/sessions/{session_id}/process", response_model=JobCreatedOut, status_code=202)
def process(session_id: int, principal: Clinician, db: DbDep, runner: RunnerDep, body: ProcessIn | None = None):
    body = body or ProcessIn()
    session = scoped_session(db, principal, session_id)
    name = body.filter or DEFAULT_METHOD
    if name not in METHODS:
        raise HTTPException(400, f"Unknown filter {name!r}; use one of {', '.join(METHODS)}.")
    ingestion = session.ingestion or {}
    if not ingestion.get("ok"):
        raise HTTPException(409, "The session's recordings are not ready to process: "
                                 f"{ingestion.get('error') or 'no recordings yet'}")
    job = Job(clinic_id=principal.clinic_id, session_id=session.id, filter=name, lang=body.lang,
              log=[], stage="queued")
    db.add(job)
    db.commit()  # committed before the runner can look for it
    runner.submit(job.id)
    return JSONResponse({"job_id": job.id}, status_code=202)


@router.get("/jobs/{job_id}", response_model=JobOut)
def get_job(job_id: int, principal: Reader, db: DbDep):
    return job_out(scoped_job(db, principal, job_id))
