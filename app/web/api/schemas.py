"""Request and response shapes of API v1 (they are the contract the browser UI is written against), and
database rows → response dicts.

Request bodies are pydantic models (422 on bad shapes, extra keys refused); responses are declared with
models too so ``/docs`` shows them.  The ``*_out`` functions build the dicts from database rows they are
given (they run no query); the session status and the shown ingestion check come from
:mod:`app.store.sessions`.
"""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from app.choices import (DEFAULT_HEADING, DEFAULT_LANGUAGE, DEFAULT_TASK, FILTER_NAMES, HEADING_NAMES, LANGUAGE_NAMES,
                         SEX_NAMES, SIDE_NAMES, TASK_NAMES, USER_ROLE_NAMES)
from app.store.models import Analysis, AuditEvent, Job, KneeSession, Patient, Recording, User
from app.store.sessions import ready, session_status, stored_ingestion

# every option list comes from app.choices (the one definition the CLI and GET /options use too)
Lang = Literal[LANGUAGE_NAMES]  # type: ignore[valid-type]
Side = Literal[SIDE_NAMES]  # type: ignore[valid-type]
RoleName = Literal[USER_ROLE_NAMES]  # type: ignore[valid-type]
TaskName = Literal[TASK_NAMES]  # type: ignore[valid-type]
FilterName = Literal[FILTER_NAMES]  # type: ignore[valid-type]
HeadingName = Literal[HEADING_NAMES]  # type: ignore[valid-type]
SEXES = SEX_NAMES  # a patient's sex as FHIR's administrative gender takes it (app.choices)
Sex = Literal[SEXES]  # type: ignore[valid-type]


class _In(BaseModel):
    model_config = ConfigDict(extra="forbid", str_strip_whitespace=True)


class LoginIn(_In):
    email: str = Field(min_length=3, max_length=320)
    password: str = Field(min_length=1, max_length=1000)
    #: the clinic's name, needed only when the email has accounts in several clinics (app.web.api.auth)
    clinic: str | None = Field(None, min_length=1, max_length=200)


class UserIn(_In):
    email: str = Field(min_length=3, max_length=320, pattern=r"^[^@\s]+@[^@\s]+$")
    name: str = Field("", max_length=200)
    role: RoleName
    #: the strength rules (at least 12 characters, …) are app.web.passwords, answered 422 in the caller's language
    password: str = Field(min_length=1, max_length=1000)


class PatientIn(_In):
    external_id: str = Field(min_length=1, max_length=100)
    side: Side
    name: str | None = Field(None, max_length=200)
    birth_date: dt.date | None = None
    sex: Sex | None = None
    height_cm: float | None = Field(None, gt=30, lt=260)
    mass_kg: float | None = Field(None, gt=2, lt=400)
    notes: str | None = Field(None, max_length=10000)


class PatientPatch(_In):
    """``PATCH /patients/{id}``: the fields to correct (absent: unchanged; ``external_id`` and ``side`` cannot be
    null)."""

    external_id: str | None = Field(None, min_length=1, max_length=100)
    side: Side | None = None
    name: str | None = Field(None, max_length=200)
    birth_date: dt.date | None = None
    sex: Sex | None = None
    height_cm: float | None = Field(None, gt=30, lt=260)
    mass_kg: float | None = Field(None, gt=2, lt=400)
    notes: str | None = Field(None, max_length=10000)


class SessionPatch(_In):
    """``PATCH /sessions/{id}``: the fields to correct (absent: unchanged; ``date`` and ``task`` cannot be null)."""

    date: dt.date | None = None
    task: TaskName | None = None
    step_height_m: float | None = Field(None, gt=0, lt=1)
    professional: str | None = Field(None, max_length=200)
    notes: str | None = Field(None, max_length=10000)


class SessionIn(_In):
    date: dt.date | None = None
    task: TaskName = DEFAULT_TASK
    step_height_m: float | None = Field(None, gt=0, lt=1)
    professional: str | None = Field(None, max_length=200)
    notes: str | None = Field(None, max_length=10000)


class ProcessIn(_In):
    filter: FilterName | None = None
    lang: Lang = DEFAULT_LANGUAGE
    heading: HeadingName = DEFAULT_HEADING
    #: the side analysed over the one the files say (as ``chakamo process --side``): a recording of the other leg
    #: is then processed, with a warning, instead of refused; None: the patient's side, checked against the files
    side: Side | None = None


class OptionOut(BaseModel):
    name: str
    label: str
    default: bool


class TaskOptionOut(OptionOut):
    phases: list[str]


class OptionsOut(BaseModel):
    """``GET /options``: every option list (:mod:`app.choices`)."""

    filters: list[OptionOut]
    tasks: list[TaskOptionOut]
    languages: list[OptionOut]
    calibrations: list[OptionOut]
    angle_conventions: list[OptionOut]
    headings: list[OptionOut]
    sides: list[OptionOut]


class ClinicOut(BaseModel):
    id: int
    name: str


class UserOut(BaseModel):
    id: int
    email: str
    name: str
    role: str
    clinic: ClinicOut


class MeOut(BaseModel):
    user: UserOut | None
    csrf_token: str | None


class PatientOut(BaseModel):
    id: int
    external_id: str
    side: str
    name: str | None
    birth_date: dt.date | None
    sex: str | None
    height_cm: float | None
    mass_kg: float | None
    notes: str | None
    created_at: dt.datetime
    version: int
    updated_at: dt.datetime | None


class RecordingOut(BaseModel):
    id: int
    file_name: str
    size_bytes: int
    sha256: str
    segment: str | None
    role: str | None
    #: the sensor's serial from the file (a MetaBase MAC), stored at upload; null when the file names none
    device: str | None = None
    uploaded_at: dt.datetime


class IngestionOut(BaseModel):
    ok: bool
    messages: list[str]
    error: str | None


class JobOut(BaseModel):
    id: int
    session_id: int
    status: Literal["queued", "running", "done", "failed"]
    progress: float
    stage: str
    error: str | None
    #: a failed job's message as a catalogue code and values (app.pipeline.messages), and rendered per language
    error_code: str | None = None
    error_params: dict[str, Any] | None = None
    error_message: dict[str, str] | None = None
    log: list[str]
    analysis_id: int | None
    filter: str
    lang: str
    #: the side chosen over the files' (the process request's ``side``), or null
    side: str | None = None
    created_at: dt.datetime
    started_at: dt.datetime | None
    finished_at: dt.datetime | None


class AnalysisOut(BaseModel):
    id: int
    job_id: int
    filter: str
    created_at: dt.datetime
    accepted_cycles: int
    warnings: int
    superseded_at: dt.datetime | None


class SessionSummaryOut(BaseModel):
    id: int
    patient_id: int
    date: dt.date
    task: str
    created_at: dt.datetime
    n_recordings: int
    status: Literal["empty", "incomplete", "ready", "processing", "done", "failed", "superseded"]


class SessionOut(SessionSummaryOut):
    version: int
    updated_at: dt.datetime | None
    step_height_m: float | None
    professional: str | None
    notes: str | None
    recordings: list[RecordingOut]
    #: the stored sensor serials' provenance check (one sensor on both segments): ``{"code", "params", "message":
    #: {lang: text}}`` each (app.pipeline.ingestion.provenance.check_stored_sensors)
    sensor_warnings: list[dict[str, Any]] = []
    ingestion: IngestionOut
    analyses: list[AnalysisOut]
    jobs: list[JobOut]


class UploadOut(BaseModel):
    recordings: list[RecordingOut]
    ingestion: IngestionOut


class JobCreatedOut(BaseModel):
    job_id: int


class TrendPoint(BaseModel):
    session_id: int
    date: dt.date
    analysis_id: int
    filter: str
    rom_deg: dict[str, Any]


class TrendOut(BaseModel):
    points: list[TrendPoint]


class AuditEventOut(BaseModel):
    """One audit event (:mod:`app.web.audit`): ``actor_kind`` is ``user``, ``token``, ``anonymous`` (a failed
    login, a request without valid credentials) or ``operator`` (the command line); ``resource`` is the
    request's method and path; ``client`` the caller's address; ``status`` the answer's code of a security
    event and ``detail`` what changed or why it was refused."""

    id: int
    at: dt.datetime
    actor_kind: Literal["user", "token", "anonymous", "operator"]
    user_id: int | None
    token_id: int | None
    actor: str
    action: str
    patient_id: int | None
    session_id: int | None
    resource: str
    client: str
    status: int | None = None
    detail: str = ""


def user_out(u: User) -> dict[str, Any]:
    return {"id": u.id, "email": u.email, "name": u.name, "role": u.role,
            "clinic": {"id": u.clinic.id, "name": u.clinic.name}}


def patient_out(p: Patient) -> dict[str, Any]:
    return {k: getattr(p, k) for k in ("id", "external_id", "side", "name", "birth_date", "sex", "height_cm",
                                       "mass_kg", "notes", "created_at", "version", "updated_at")}


def recording_out(r: Recording) -> dict[str, Any]:
    return {k: getattr(r, k) for k in ("id", "file_name", "size_bytes", "sha256", "segment", "role", "device",
                                       "uploaded_at")}


def job_out(j: Job) -> dict[str, Any]:
    out = {k: getattr(j, k) for k in ("id", "session_id", "status", "progress", "stage", "error", "error_code",
                                      "error_params", "log", "analysis_id", "filter", "lang", "side", "created_at",
                                      "started_at", "finished_at")}
    if j.error_code:
        from app.pipeline.messages import message_dict

        out["error_message"] = message_dict(j.error_code, j.error_params or {})["message"]
    return out


def audit_out(e: AuditEvent) -> dict[str, Any]:
    return {k: getattr(e, k) for k in ("id", "at", "actor_kind", "user_id", "token_id", "actor", "action",
                                       "patient_id", "session_id", "resource", "client", "status", "detail")}


def analysis_out(a: Analysis) -> dict[str, Any]:
    return {k: getattr(a, k) for k in ("id", "job_id", "filter", "created_at", "accepted_cycles", "warnings",
                                       "superseded_at")}


def summaries(sessions: list[KneeSession], counts: dict[int, int], latest: dict[int, Job],
              superseded: set[int] | None = None) -> list[dict[str, Any]]:
    """SessionSummary dicts of ``sessions`` from :func:`app.store.sessions.summary_facts`."""
    superseded = superseded or set()
    return [summary_out(s, counts.get(s.id, 0), latest.get(s.id), s.id in superseded) for s in sessions]


def summary_out(s: KneeSession, n_recordings: int, latest_job: Job | None, superseded: bool = False) -> dict[str, Any]:
    return {"id": s.id, "patient_id": s.patient_id, "date": s.date, "task": s.task, "created_at": s.created_at,
            "n_recordings": n_recordings, "status": session_status(n_recordings, ready(s), latest_job, superseded)}


def sensor_warnings(recs: list[Recording]) -> list[dict[str, Any]]:
    """The provenance check of the serials stored with ``recs`` (upload segment + device), each finding in
    es/en/pt."""
    from app.pipeline.ingestion.messages import message_dict
    from app.pipeline.ingestion.provenance import check_stored_sensors

    found = check_stored_sensors((r.file_name, r.segment, r.device) for r in recs)
    return [message_dict(f.code, f.params) for f in found]


def session_out(s: KneeSession, jobs: list[Job], analyses: list[Analysis]) -> dict[str, Any]:
    """The Session dict of ``s`` with its jobs and analyses, newest first (:func:`app.store.sessions.session_jobs`,
    :func:`app.store.sessions.session_analyses`)."""
    recs = list(s.recordings)
    latest = jobs[0] if jobs else None
    superseded = latest is not None and any(a.id == latest.analysis_id and a.superseded_at is not None
                                            for a in analyses)
    out = summary_out(s, len(recs), latest, superseded)
    out |= {"version": s.version, "updated_at": s.updated_at, "step_height_m": s.step_height_m,
            "professional": s.professional, "notes": s.notes,
            "recordings": [recording_out(r) for r in recs], "sensor_warnings": sensor_warnings(recs),
            "ingestion": stored_ingestion(s, len(recs)),
            "analyses": [analysis_out(a) for a in analyses], "jobs": [job_out(j) for j in jobs]}
    return out
