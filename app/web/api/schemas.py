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

from app.choices import (ANGLE_CONVENTION_NAMES, CALIBRATION_NAMES, DEFAULT_ANGLE_CONVENTION, DEFAULT_CALIBRATION,
                         DEFAULT_HEADING, DEFAULT_LANGUAGE, DEFAULT_TASK, FILTER_NAMES, HEADING_NAMES, LANGUAGE_NAMES,
                         MEASURE_RANGES, SEX_NAMES, SIDE_NAMES, TASK_NAMES, USER_ROLE_NAMES)
from app.store.models import Analysis, AuditEvent, Job, KneeSession, Patient, Recording, User
from app.store.sessions import ready, session_status, stored_ingestion
from app.web.fhir import PATIENT_REFERENCE
from app.web.webhooks import trail_error

# every option list comes from app.choices (the one definition the CLI and GET /options use too)
Lang = Literal[LANGUAGE_NAMES]  # type: ignore[valid-type]
Side = Literal[SIDE_NAMES]  # type: ignore[valid-type]
RoleName = Literal[USER_ROLE_NAMES]  # type: ignore[valid-type]
TaskName = Literal[TASK_NAMES]  # type: ignore[valid-type]
FilterName = Literal[FILTER_NAMES]  # type: ignore[valid-type]
HeadingName = Literal[HEADING_NAMES]  # type: ignore[valid-type]
CalibrationName = Literal[CALIBRATION_NAMES]  # type: ignore[valid-type]
AngleConventionName = Literal[ANGLE_CONVENTION_NAMES]  # type: ignore[valid-type]
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


_PATIENT_REFERENCE_TEXT = ("the hospital's FHIR Patient: Patient/<id> or its absolute URL (the reports' subject with "
                           "CHAKAMO_FHIR_PATIENT=reference)")


class PatientIn(_In):
    external_id: str = Field(min_length=1, max_length=100)
    side: Side
    name: str | None = Field(None, max_length=200)
    birth_date: dt.date | None = None
    sex: Sex | None = None
    height_cm: float | None = Field(None, gt=MEASURE_RANGES["height_cm"][0], lt=MEASURE_RANGES["height_cm"][1])
    mass_kg: float | None = Field(None, gt=MEASURE_RANGES["mass_kg"][0], lt=MEASURE_RANGES["mass_kg"][1])
    notes: str | None = Field(None, max_length=10000)
    fhir_reference: str | None = Field(None, max_length=300, pattern=PATIENT_REFERENCE.pattern,
                                       description=_PATIENT_REFERENCE_TEXT)


class PatientPatch(_In):
    """``PATCH /patients/{id}``: the fields to correct (absent: unchanged; ``external_id`` and ``side`` cannot be
    null)."""

    external_id: str | None = Field(None, min_length=1, max_length=100)
    side: Side | None = None
    name: str | None = Field(None, max_length=200)
    birth_date: dt.date | None = None
    sex: Sex | None = None
    height_cm: float | None = Field(None, gt=MEASURE_RANGES["height_cm"][0], lt=MEASURE_RANGES["height_cm"][1])
    mass_kg: float | None = Field(None, gt=MEASURE_RANGES["mass_kg"][0], lt=MEASURE_RANGES["mass_kg"][1])
    notes: str | None = Field(None, max_length=10000)
    fhir_reference: str | None = Field(None, max_length=300, pattern=PATIENT_REFERENCE.pattern,
                                       description=_PATIENT_REFERENCE_TEXT)


#: a FHIR reference to a resource of one type: relative (``Type/id``) or absolute (``https://…/Type/id``)
_SERVICE_REQUEST = r"^(https?://\S+/)?ServiceRequest/[A-Za-z0-9\-.]{1,64}$"
_ENCOUNTER = r"^(https?://\S+/)?Encounter/[A-Za-z0-9\-.]{1,64}$"


class SessionPatch(_In):
    """``PATCH /sessions/{id}``: the fields to correct (absent: unchanged; ``date`` and ``task`` cannot be null)."""

    date: dt.date | None = None
    task: TaskName | None = None
    step_height_m: float | None = Field(None, gt=0, lt=1)
    professional: str | None = Field(None, max_length=200)
    notes: str | None = Field(None, max_length=10000)
    service_request: str | None = Field(None, max_length=300, pattern=_SERVICE_REQUEST,
                                        description="the order: ServiceRequest/<id> or its absolute URL (FHIR basedOn)")
    encounter: str | None = Field(None, max_length=300, pattern=_ENCOUNTER,
                                  description="the visit: Encounter/<id> or its absolute URL (FHIR encounter)")
    accession: str | None = Field(None, max_length=100, description="the accession number of the order")


class SessionIn(_In):
    date: dt.date | None = None
    task: TaskName = DEFAULT_TASK
    step_height_m: float | None = Field(None, gt=0, lt=1)
    professional: str | None = Field(None, max_length=200)
    notes: str | None = Field(None, max_length=10000)
    service_request: str | None = Field(None, max_length=300, pattern=_SERVICE_REQUEST,
                                        description="the order: ServiceRequest/<id> or its absolute URL (FHIR basedOn)")
    encounter: str | None = Field(None, max_length=300, pattern=_ENCOUNTER,
                                  description="the visit: Encounter/<id> or its absolute URL (FHIR encounter)")
    accession: str | None = Field(None, max_length=100, description="the accession number of the order")


class CycleExclusionIn(_In):
    """One cycle the clinician leaves out: its number as the reports show it (from 1), its knee in a session of
    both knees (null for the only knee), and why."""

    cycle: int = Field(ge=1, le=10_000)
    knee: Side | None = None
    reason: str = Field(default="", max_length=300)


class PairIn(_In):
    """Pair this one-knee session with another of the patient's, of the other knee (both knees' view and LSI)."""

    session_id: int = Field(ge=1)
    #: the knee this session's recordings measure (the other session's is the other): required, never defaulted
    #: (a default could swap the knees); checked against the side the session's file names say, when they say one
    knee: Side


class ProcessIn(_In):
    filter: FilterName | None = None
    lang: Lang = DEFAULT_LANGUAGE
    heading: HeadingName = DEFAULT_HEADING
    #: the side analysed over the one the files say (as ``chakamo process --side``): a recording of the other leg
    #: is then processed, with a warning, instead of refused; None: the patient's side, checked against the files
    side: Side | None = None
    #: the involved knee of a two-knee session (as ``chakamo process --involved``): the numerator of the limb
    #: symmetry index in results.json ``symmetry``; None: the patient's side
    involved: Side | None = None
    #: the sensor-to-segment calibration (as ``chakamo process --calibration``): ``static`` (standing + supine) or
    #: ``functional`` (standing + the knee's flexion axis on the task)
    calibration: CalibrationName = DEFAULT_CALIBRATION
    #: the knee-angle convention (as ``chakamo process --angles``): Grood & Suntay or the thesis' ZYX Euler angles
    angle_convention: AngleConventionName = DEFAULT_ANGLE_CONVENTION
    #: the cycles to leave out, each with the clinician's reason (the results page's per-cycle choice, as ``chakamo
    #: process --exclude-cycles``); the whole set each time: a cycle not named is included again.  Given (an empty
    #: list too) the new analysis supersedes the session's earlier ones of the same calibration and angle convention
    #: and records who excluded which cycle and why; null: an ordinary processing, which keeps the current
    #: analysis' exclusions (of the same files and pipeline version)
    exclude_cycles: list[CycleExclusionIn] | None = Field(default=None, max_length=200)
    #: required with ``exclude_cycles``: the analysis the cycles were chosen on.  409 unless it is the session's
    #: current analysis (latest, not superseded, of the current files and pipeline version); its options (filter,
    #: heading, side, involved knee, calibration, angle convention) are copied and the request's are ignored
    based_on_analysis_id: int | None = Field(default=None, ge=1)


class OptionOut(BaseModel):
    name: str
    label: str
    default: bool


class TaskOptionOut(OptionOut):
    phases: list[str]


class StillnessChecksOut(BaseModel):
    """The postures' live stillness check: the pipeline's still window (s) and its limits on the window's total SD
    (ddof 1) of the gyroscope (rad/s) and the accelerometer (m/s²) (estimators.knee)."""

    window_s: float
    max_gyr_sd_rad_s: float
    max_acc_sd_m_s2: float


class CoverageChecksOut(BaseModel):
    """The figure-eight's live sphere coverage: samples a direction cell needs, the share of the 20 cells below
    which the pipeline warns (estimators.magnetometer), the live-only least field from the hard-iron estimate (µT)."""

    min_cell_samples: int
    complete_fraction: float
    min_field_ut: float


class CycleChecksOut(BaseModel):
    """The task's live cycle count (live-only): averaging window (s), rise and fall thresholds (rad/s)."""

    average_s: float
    rise_rad_s: float
    fall_rad_s: float


class LiveChecksOut(BaseModel):
    """The recording page's live checks' thresholds (:func:`app.choices.live_checks`)."""

    stillness: StillnessChecksOut
    coverage: CoverageChecksOut
    cycles: CycleChecksOut


class OptionsOut(BaseModel):
    """``GET /options``: every option list (:mod:`app.choices`)."""

    filters: list[OptionOut]
    tasks: list[TaskOptionOut]
    languages: list[OptionOut]
    calibrations: list[OptionOut]
    angle_conventions: list[OptionOut]
    headings: list[OptionOut]
    sides: list[OptionOut]
    #: a patient's sexes (app.choices.SEX_NAMES), what an API token may be limited to (app.choices.TOKEN_SCOPES)
    #: and the audit log's actions (app.web.audit)
    sexes: list[str]
    token_scopes: list[str]
    audit_actions: list[str]
    #: the patient measurements' open intervals (app.choices.MEASURE_RANGES), the user roles, a token's longest life
    measure_ranges: dict[str, dict[str, float]]
    roles: list[str]
    token_max_days: int
    #: the recording page's live checks' thresholds (app.choices.live_checks)
    live_checks: LiveChecksOut


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
    fhir_reference: str | None = None


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
    """The session's ingestion check: ``messages`` / ``error`` in English (as before), ``message_texts`` /
    ``error_message`` the same in every language (``{lang: text}``, from the codes the check stored:
    :func:`app.pipeline.service_messages.render_item`), and ``splits``, each sensor's continuous recording as cut
    (``spans_s``, ``duration_s``, a motion ``trace`` at ``trace_hz``) for the wizard to show and move."""

    ok: bool
    messages: list[str]
    error: str | None
    message_texts: list[dict[str, str]] = []
    error_message: dict[str, str] | None = None
    splits: dict[str, dict[str, Any]] = {}
    #: the segment and role the check recognised each stored file as (``{file name: {"segment", "role"}}``; a
    #: four-sensor session's segments carry their knee, ``left_thigh``); empty while the check fails
    recognised: dict[str, dict[str, str | None]] = {}
    #: the cuts the clinician stored (``PUT /sessions/{id}/split``), or None: the automatic split
    confirmed_split: dict[str, Any] | None = None


class SplitIn(BaseModel):
    """``PUT /sessions/{id}/split``: ``{segment: {role: [start_s, end_s]}}`` (seconds from the recording's start),
    or null to go back to the automatic split."""

    split: dict[str, dict[str, list[float]]] | None


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
    #: the involved knee chosen for a two-knee session (the process request's ``involved``), or null
    involved: str | None = None
    #: the calibration and angle convention asked for (the process request's ``calibration`` / ``angle_convention``)
    calibration: str = DEFAULT_CALIBRATION
    angle_convention: str = DEFAULT_ANGLE_CONVENTION
    #: the thigh–shank heading asked for
    heading: str = "auto"
    #: the cycles the clinician excluded for this job (who, which, why, when; chosen with it, or carried over from the
    #: current analysis), or null
    cycle_exclusions: list[dict[str, Any]] | None = None
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
    #: the sensor-to-segment calibration and knee-angle convention it was computed with
    calibration: str = DEFAULT_CALIBRATION
    angle_method: str = DEFAULT_ANGLE_CONVENTION


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
    service_request: str | None = None
    encounter: str | None = None
    accession: str | None = None
    recordings: list[RecordingOut]
    #: the stored sensor serials' provenance check (one sensor on both segments): ``{"code", "params", "message":
    #: {lang: text}}`` each (app.pipeline.ingestion.provenance.check_stored_sensors)
    sensor_warnings: list[dict[str, Any]] = []
    ingestion: IngestionOut
    analyses: list[AnalysisOut]
    jobs: list[JobOut]
    #: the session paired with this one (the other knee: processing either gives both knees and the LSI), or null
    paired_session_id: int | None = None
    #: the knee this session's recordings measure when paired (left/right); null: the patient's side
    knee: str | None = None


class PairOut(SessionOut):
    #: what the clinician should know about the pairing (sessions of different dates): ``{"code", "params",
    #: "message": {lang: text}}`` each
    warnings: list[dict[str, Any]] = []


class UploadOut(BaseModel):
    recordings: list[RecordingOut]
    ingestion: IngestionOut


class JobCreatedOut(BaseModel):
    job_id: int


class TrendPoint(BaseModel):
    session_id: int
    date: dt.date
    #: the analysis the point comes from
    analysis_id: int
    filter: str
    pipeline_version: str
    calibration: str
    angle_method: str
    #: the knee ``rom_deg`` describes: the patient's (in a session of both knees too)
    side: str | None = None
    rom_deg: dict[str, Any]


class TrendSeries(BaseModel):
    """One filter, pipeline version, calibration and angle convention among the patient's analyses, and how many
    sessions it covers."""
    filter: str
    pipeline_version: str
    calibration: str
    angle_method: str
    sessions: int


class TrendLeftOut(BaseModel):
    """A session with analyses, none of the trend's series: which ones it has."""
    session_id: int
    date: dt.date
    analyses: list[dict[str, Any]]


class TrendOut(BaseModel):
    """``GET /patients/{id}/trend``: the points of one series (filter, pipeline version, calibration and angle
    convention) only."""
    filter: str | None
    pipeline_version: str | None
    calibration: str | None
    angle_method: str | None
    points: list[TrendPoint]
    left_out: list[TrendLeftOut]
    series: list[TrendSeries]


class CompareSide(BaseModel):
    session_id: int
    date: dt.date
    task: str | None
    side: str | None
    involved_side: str | None = None
    analysis_id: int
    filter: str
    pipeline_version: str
    calibration: str
    angle_method: str
    accepted_cycles: int


class CompareRow(BaseModel):
    """One number of both sessions: ``key`` its path in results.json, ``change`` = b − a."""
    key: str
    unit: str
    a: float | None
    b: float | None
    change: float | None


class CompareOut(BaseModel):
    """``GET /patients/{id}/compare?a=&b=``: two sessions side by side (:mod:`app.store.comparisons`)."""
    a: CompareSide
    b: CompareSide
    comparable: bool
    mismatch: list[str]
    rows: list[CompareRow]


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
                                       "mass_kg", "notes", "created_at", "version", "updated_at", "fhir_reference")}


def recording_out(r: Recording) -> dict[str, Any]:
    return {k: getattr(r, k) for k in ("id", "file_name", "size_bytes", "sha256", "segment", "role", "device",
                                       "uploaded_at")}


def job_out(j: Job) -> dict[str, Any]:
    out = {k: getattr(j, k) for k in ("id", "session_id", "status", "progress", "stage", "error", "error_code",
                                      "error_params", "log", "analysis_id", "filter", "lang", "side", "involved",
                                      "heading", "cycle_exclusions", "created_at",
                                      "started_at", "finished_at")}
    out |= {"calibration": j.calibration, "angle_convention": j.angle_method}
    if j.error_code:
        from app.pipeline.messages import message_dict

        out["error_message"] = message_dict(j.error_code, j.error_params or {})["message"]
    return out


def audit_out(e: AuditEvent) -> dict[str, Any]:
    return {k: getattr(e, k) for k in ("id", "at", "actor_kind", "user_id", "token_id", "actor", "action",
                                       "patient_id", "session_id", "resource", "client", "status", "detail")}


def analysis_out(a: Analysis) -> dict[str, Any]:
    return {k: getattr(a, k) for k in ("id", "job_id", "filter", "created_at", "accepted_cycles", "warnings",
                                       "superseded_at", "calibration", "angle_method")}


def summaries(sessions: list[KneeSession], counts: dict[int, int], latest: dict[int, Job],
              superseded: set[int] | None = None) -> list[dict[str, Any]]:
    """SessionSummary dicts of ``sessions`` from :func:`app.store.sessions.summary_facts`."""
    superseded = superseded or set()
    return [summary_out(s, counts.get(s.id, 0), latest.get(s.id), s.id in superseded) for s in sessions]


def summary_out(s: KneeSession, n_recordings: int, latest_job: Job | None, superseded: bool = False) -> dict[str, Any]:
    return {"id": s.id, "patient_id": s.patient_id, "date": s.date, "task": s.task, "created_at": s.created_at,
            "n_recordings": n_recordings, "status": session_status(n_recordings, ready(s), latest_job, superseded)}


def sensor_warnings(recs: list[Recording], segments: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """The provenance check of the serials stored with ``recs`` (the segment declared at upload, else the one the
    check recognised, ``segments`` by file name; and the device), each finding in es/en/pt."""
    from app.pipeline.ingestion.messages import message_dict
    from app.pipeline.ingestion.provenance import check_stored_sensors

    segments = segments or {}
    found = check_stored_sensors((r.file_name, r.segment or segments.get(r.file_name), r.device) for r in recs)
    return [message_dict(f.code, f.params) for f in found]


def ingestion_out(stored: dict[str, Any], confirmed: dict[str, Any] | None = None) -> dict[str, Any]:
    """The IngestionOut of a stored check (:func:`app.store.checks.ingestion_view`) and the stored cuts."""
    from app.store.checks import ingestion_view

    roles = stored.get("roles") or {}
    recognised = {name: {"segment": seg, "role": roles.get(name)} for name, seg in (stored.get("segments") or {}).items()}
    return ingestion_view(stored) | {"confirmed_split": confirmed, "recognised": recognised}


def pair_out(s: KneeSession, jobs: list[Job], analyses: list[Analysis], warnings: list[dict]) -> dict[str, Any]:
    """:func:`session_out` with the pairing's warnings (``{"code", "params"}``, app.store.pairing) in es/en/pt."""
    from app.pipeline.service_messages import message_dict

    return {**session_out(s, jobs, analyses), "warnings": [message_dict(w["code"], w["params"]) for w in warnings]}


def session_out(s: KneeSession, jobs: list[Job], analyses: list[Analysis]) -> dict[str, Any]:
    """The Session dict of ``s`` with its jobs and analyses, newest first (:func:`app.store.sessions.session_jobs`,
    :func:`app.store.sessions.session_analyses`)."""
    recs = list(s.recordings)
    latest = jobs[0] if jobs else None
    superseded = latest is not None and any(a.id == latest.analysis_id and a.superseded_at is not None
                                            for a in analyses)
    out = summary_out(s, len(recs), latest, superseded)
    out |= {"version": s.version, "updated_at": s.updated_at, "step_height_m": s.step_height_m,
            "professional": s.professional, "notes": s.notes, "service_request": s.service_request,
            "encounter": s.encounter, "accession": s.accession,
            "recordings": [recording_out(r) for r in recs],
            "sensor_warnings": sensor_warnings(recs, stored_ingestion(s, len(recs)).get("segments")),
            "ingestion": ingestion_out(stored_ingestion(s, len(recs)), s.split),
            "analyses": [analysis_out(a) for a in analyses], "jobs": [job_out(j) for j in jobs],
            "paired_session_id": s.paired_session_id, "knee": s.knee}
    return out


class TrailError(BaseModel):
    code: str = Field(description="webhook.no_connection, webhook.http_status, webhook.secret_unreadable, "
                                  "fhir.not_exportable, fhir.patient_reference_invalid or fhir.patient_unreferenced")
    params: dict = Field(description="the values the message names (status, seconds)")
    message: dict[str, str] = Field(description="the sentence in es, en and pt")


class DeliveryOut(BaseModel):
    id: int
    event: str
    job_id: int
    state: str
    attempts: int
    last_status: int | None
    last_error: str = Field(description="the last failed attempt in English (\"\" when none failed); `error` has its "
                                        "code and the sentence in es/en/pt")
    error: TrailError | None = None
    created_at: dt.datetime
    delivered_at: dt.datetime | None
    next_attempt_at: dt.datetime | None


def delivery_out(d) -> dict:
    """A delivery row as :class:`DeliveryOut` (its error code rendered by :func:`app.web.webhooks.trail_error`)."""
    error = trail_error(d.last_error, d.last_status, d.state)
    return {"id": d.id, "event": d.event, "job_id": d.job_id, "state": d.state, "attempts": d.attempts,
            "last_status": d.last_status, "last_error": error["message"]["en"] if error else "", "error": error,
            "created_at": d.created_at, "delivered_at": d.delivered_at,
            "next_attempt_at": d.next_attempt_at if d.state == "pending" else None}
