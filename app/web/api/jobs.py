"""Processing: ``POST /sessions/{id}/process`` queues a job; ``GET /jobs/{id}`` follows it.

The rules are :func:`app.jobs.queue.enqueue`'s (the same for ``chakamo reprocess``): while a job of the
session is queued or running a new request answers 409 (checked before and, for SQLite's concurrent writers,
again after inserting); a stale ingestion check (files changed since) is redone before deciding (409 when it
is not ok).  The job row is committed before the runner hears of it, so a crash between the two loses nothing
(the runner's start-up resubmits queued jobs).  Every analysis is kept: processing again (e.g. with another
filter) adds one; a choice of cycles (``exclude_cycles``) marks the earlier analyses of its own calibration and
angle convention superseded (they stay readable by id).
"""

from fastapi import APIRouter, Request

from app.choices import DEFAULT_FILTER
from app.jobs.queue import enqueue, hand_over
from app.store import idempotency
from app.store.sessions import Busy
from app.web import audit
from app.web.api.deps import CheckerDep, Clinician, DbDep, Reader, RunnerDep, scoped_job, scoped_session
from app.web.api.schemas import JobCreatedOut, JobOut, ProcessIn, job_out
from app.web.idempotency import KEY_PARAMETER, LOCATION, answer, key_of, request_sha256

router = APIRouter(tags=["jobs"])


@router.post("/sessions/{session_id}/process", response_model=JobCreatedOut, status_code=202,
             openapi_extra={"parameters": [KEY_PARAMETER]},
             responses={202: {"headers": LOCATION},
                        409: {"description": "recordings not ready, the session is being processed, or the "
                                             "Idempotency-Key was used for another request"}})
def process(session_id: int, principal: Clinician, db: DbDep, runner: RunnerDep, checker: CheckerDep,
            request: Request, body: ProcessIn | None = None):
    """Queue the processing (``Location``: the job).  With ``Idempotency-Key`` a repeat — also after the job
    finished — answers the same job and starts nothing."""
    body = body or ProcessIn()
    key = key_of(request)
    fingerprint = request_sha256(request, body)
    replay = idempotency.replayed(db, principal.clinic_id, key, fingerprint) if key else None
    if replay is None:
        name = body.filter or DEFAULT_FILTER  # the schema accepts only app.choices.FILTER_NAMES
        try:
            job = enqueue(db, principal.clinic_id, session_id, filter_name=name, lang=body.lang, checker=checker,
                          heading=body.heading, side=body.side, involved=body.involved,
                          calibration=body.calibration, angle_method=body.angle_convention,
                          cycle_exclusions=_exclusions(body, principal), based_on=body.based_on_analysis_id)
        except Busy:  # busy with the job a concurrent request with this key just committed?
            db.rollback()
            replay = idempotency.replayed(db, principal.clinic_id, key, fingerprint) if key else None
            if replay is None:
                raise
    if replay is None and key:  # claimed after enqueue, which may roll db back (its ingestion check)
        claimed = idempotency.claim(db, principal.clinic_id, key, fingerprint, "job")
        if isinstance(claimed, idempotency.Replay):
            replay = claimed
        else:
            idempotency.complete(claimed, [job.id], 202)
    if replay is not None:
        job = scoped_job(db, principal, replay.resource_ids[0])
        return answer({"job_id": job.id}, replay.status, f"/api/v1/jobs/{job.id}", replayed=True)
    session = scoped_session(db, principal, session_id)  # the row enqueue loaded (no new query)
    audit.record(db, request, principal, "process", patient_id=session.patient_id, session_id=session.id,
                 detail=_exclusions_detail(job, chosen=body.exclude_cycles is not None))
    db.commit()  # committed before the runner can look for it
    hand_over(runner, job.id)
    return answer({"job_id": job.id}, 202, f"/api/v1/jobs/{job.id}")


def _exclusions(body: ProcessIn, principal) -> tuple[list[dict], str] | None:
    """The request's cycle exclusions and who asks (the user's email, or the API token); None when it named none."""
    if body.exclude_cycles is None:
        return None
    by = principal.user.email if principal.user is not None else f"token {principal.token_id}"
    return [x.model_dump() for x in body.exclude_cycles], by


def _exclusions_detail(job, chosen: bool) -> str:
    """The audit event's short detail of a processing that changes which cycles count (the reasons are the job's:
    ``GET /jobs/{id}`` ``cycle_exclusions``); ``chosen``: the request named them (else they were carried over from
    the analysis before, a choice audited when it was made)."""
    if job.cycle_exclusions is None:
        return ""
    if not chosen:
        return f"job {job.id}: the cycles excluded before are carried over"
    named = ", ".join(f"{e['knee'] + ':' if e['knee'] else ''}{e['cycle']}" for e in job.cycle_exclusions)
    if len(named) > 120:
        named = f"{len(job.cycle_exclusions)} cycles"
    return f"job {job.id}: cycles excluded: {named or 'none (all included again)'}; reasons on the job"


@router.get("/jobs/{job_id}", response_model=JobOut)
def get_job(job_id: int, principal: Reader, db: DbDep):
    return job_out(scoped_job(db, principal, job_id))
