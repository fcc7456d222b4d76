"""The database tables (SQLAlchemy 2 typed declarative models).

Tenancy: every row belongs to a clinic, directly (``clinic_id`` on users, tokens, patients, sessions,
jobs) or through its parent (recordings, analyses, artefacts through their session); the API scopes every
query by the caller's clinic.  Files are not in the database: :class:`Blob` rows name content-addressed
files (``app.store.blobs``) by sha256, shared by recordings and artefacts with equal content.

Times are stored as naive UTC and come back timezone-aware (:class:`UTCDateTime`), so the API prints
ISO 8601 with ``+00:00``.  Job logs are JSON lists of lines.  Changing a model means adding an Alembic
revision under ``app/store/migrations/versions`` (a test compares the two).
"""

from __future__ import annotations

import datetime as dt

from sqlalchemy import (JSON, Boolean, Date, DateTime, Float, ForeignKey, Index, Integer, MetaData, String, Text,
                        TypeDecorator, UniqueConstraint, text)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

from app.choices import DEFAULT_ANGLE_CONVENTION, DEFAULT_CALIBRATION, DEFAULT_HEADING
from app.choices import USER_ROLE_NAMES as ROLES  # the one definition of the roles (re-exported here)

JOB_STATES = ("queued", "running", "done", "failed")

NAMING = {"ix": "ix_%(column_0_label)s", "uq": "uq_%(table_name)s_%(column_0_name)s",
          "ck": "ck_%(table_name)s_%(constraint_name)s",
          "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s", "pk": "pk_%(table_name)s"}


def utcnow() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc)


class UTCDateTime(TypeDecorator):
    """Timezone-aware UTC datetimes in and out, stored as naive UTC (SQLite has no time zones)."""

    impl = DateTime
    cache_ok = True

    def process_bind_param(self, value, dialect):
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime given to a UTC column; use datetime.now(timezone.utc)")
        return value.astimezone(dt.timezone.utc).replace(tzinfo=None)

    def process_result_value(self, value, dialect):
        return None if value is None else value.replace(tzinfo=dt.timezone.utc)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)


class Clinic(Base):
    __tablename__ = "clinics"
    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)


class User(Base):
    __tablename__ = "users"
    #: an account is a clinic's: one email may have an account in several clinics, at most one in each (its
    #: first column, the email, also serves the login's lookup by email)
    __table_args__ = (UniqueConstraint("email", "clinic_id", name="uq_users_email_clinic"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    email: Mapped[str] = mapped_column(String(320))  # login name, unique within its clinic
    name: Mapped[str] = mapped_column(String(200), default="")
    role: Mapped[str] = mapped_column(String(20))
    password_hash: Mapped[str] = mapped_column(String(300))
    active: Mapped[bool] = mapped_column(Boolean, default=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    clinic: Mapped[Clinic] = relationship(lazy="joined")


class ApiToken(Base):
    __tablename__ = "api_tokens"
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    label: Mapped[str] = mapped_column(String(200), default="")
    role: Mapped[str] = mapped_column(String(20), default="clinician")
    token_sha256: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    revoked_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    #: refused from this time on (null: never; a rotated token keeps working until its grace period ends)
    expires_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    #: space-separated scopes (``app.choices.TOKEN_SCOPES``) the token may use within its role; null: all of them
    scopes: Mapped[str | None] = mapped_column(String(300), nullable=True)
    clinic: Mapped[Clinic] = relationship(lazy="joined")


class BrowserSession(Base):
    __tablename__ = "browser_sessions"
    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    session_sha256: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    expires_at: Mapped[dt.datetime] = mapped_column(UTCDateTime)
    #: where and with what it was opened (shown in the user's list of their sessions)
    client: Mapped[str] = mapped_column(String(64), default="", server_default="")
    user_agent: Mapped[str] = mapped_column(String(200), default="", server_default="")
    user: Mapped[User] = relationship(lazy="joined")


class Blob(Base):
    __tablename__ = "blobs"
    sha256: Mapped[str] = mapped_column(String(64), primary_key=True)
    size_bytes: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)


class Patient(Base):
    __tablename__ = "patients"
    __table_args__ = (UniqueConstraint("clinic_id", "external_id", name="uq_patients_clinic_external"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    external_id: Mapped[str] = mapped_column(String(100))
    side: Mapped[str] = mapped_column(String(5))
    name: Mapped[str | None] = mapped_column(String(200), nullable=True)
    birth_date: Mapped[dt.date | None] = mapped_column(Date, nullable=True)
    sex: Mapped[str | None] = mapped_column(String(20), nullable=True)
    height_cm: Mapped[float | None] = mapped_column(Float, nullable=True)
    mass_kg: Mapped[float | None] = mapped_column(Float, nullable=True)
    notes: Mapped[str | None] = mapped_column(Text, nullable=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    #: bumped by every correction (PATCH): the ``ETag`` a ``DELETE`` / ``PATCH`` names in ``If-Match``
    version: Mapped[int] = mapped_column(Integer, default=1, server_default="1")
    updated_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    #: the hospital's own FHIR Patient (``Patient/<id>`` or its absolute URL), when it gave one: the exported and
    #: pushed reports' ``subject.reference`` with ``CHAKAMO_FHIR_PATIENT=reference`` (``app.web.fhir``)
    fhir_reference: Mapped[str | None] = mapped_column(String(300), nullable=True)


class KneeSession(Base):
    """One clinical session of a patient (table ``sessions``; named so to not clash with ORM sessions)."""

    __tablename__ = "sessions"
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    patient_id: Mapped[int] = mapped_column(ForeignKey("patients.id", ondelete="CASCADE"), index=True)
    date: Mapped[dt.date] = mapped_column(Date)
    task: Mapped[str] = mapped_column(String(40), default="step_up")
    step_height_m: Mapped[float | None] = mapped_column(Float, nullable=True)
    professional: Mapped[str | None] = mapped_column(String(200), nullable=True)
    notes: Mapped[str | None] = mapped_column(Text, nullable=True)
    #: the order and visit the session answers, as the hospital sent them (FHIR ``basedOn``, ``encounter``,
    #: the accession identifier): references such as ``ServiceRequest/123``, ``Encounter/456``; not in the manifest
    service_request: Mapped[str | None] = mapped_column(String(300), nullable=True)
    encounter: Mapped[str | None] = mapped_column(String(300), nullable=True)
    accession: Mapped[str | None] = mapped_column(String(100), nullable=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    #: the last ingestion check over all stored files (``{"ok", "messages", "error"}``), refreshed on every change
    ingestion: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    #: bumped (in the same transaction) by every upload or deletion of a recording
    files_version: Mapped[int] = mapped_column(Integer, default=0, server_default="0")
    #: the ``files_version`` the stored ``ingestion`` was computed from (fresh when equal)
    ingestion_version: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: bumped by every correction (PATCH): the ``ETag`` a ``DELETE`` / ``PATCH`` names in ``If-Match``
    version: Mapped[int] = mapped_column(Integer, default=1, server_default="1")
    updated_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    #: the clinician's cuts of the continuous recordings (``session.json`` ``"split"``), or None: the automatic ones
    split: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    #: a one-knee session paired with another of the patient, of the other knee (both knees' view and the limb
    #: symmetry index, app.store.pairing); None: not paired.  ``knee``: the knee its recordings measure then
    #: (left/right); None: the patient's side.  No foreign key (a rebuild of this table on SQLite would cascade to
    #: every recording): a partner since erased reads as no partner
    paired_session_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    knee: Mapped[str | None] = mapped_column(String(5), nullable=True)
    patient: Mapped[Patient] = relationship(lazy="joined")
    recordings: Mapped[list["Recording"]] = relationship(order_by="Recording.id", back_populates="session",
                                                          cascade="all, delete-orphan")


class Recording(Base):
    __tablename__ = "recordings"
    __table_args__ = (UniqueConstraint("session_id", "file_name", name="uq_recordings_session_file"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), index=True)
    file_name: Mapped[str] = mapped_column(String(255))
    size_bytes: Mapped[int] = mapped_column(Integer)
    sha256: Mapped[str] = mapped_column(ForeignKey("blobs.sha256"), index=True)
    segment: Mapped[str | None] = mapped_column(String(10), nullable=True)
    role: Mapped[str | None] = mapped_column(String(20), nullable=True)
    #: the sensor's serial the file carries (a MetaBase MAC from its name), stored at upload; None when it has none
    device: Mapped[str | None] = mapped_column(String(64), nullable=True)
    uploaded_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    session: Mapped[KneeSession] = relationship(back_populates="recordings")


class Job(Base):
    __tablename__ = "jobs"
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), index=True)
    status: Mapped[str] = mapped_column(String(10), default="queued", index=True)
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    stage: Mapped[str] = mapped_column(String(40), default="queued")
    error: Mapped[str | None] = mapped_column(Text, nullable=True)
    log: Mapped[list] = mapped_column(JSON, default=list)
    filter: Mapped[str] = mapped_column(String(40))
    lang: Mapped[str] = mapped_column(String(2), default="es")
    #: the thigh–shank heading asked for (app.choices.HEADINGS), handed to the pipeline as ProcessOptions.heading
    heading: Mapped[str] = mapped_column(String(20), default=DEFAULT_HEADING, server_default=DEFAULT_HEADING)
    #: the side the clinician chose over the files' (ProcessOptions.side, kept as a warning); None: the files'
    side: Mapped[str | None] = mapped_column(String(5), nullable=True)
    #: the involved knee of a two-knee session (ProcessOptions.involved: the LSI's numerator); None: the patient's
    involved: Mapped[str | None] = mapped_column(String(5), nullable=True)
    #: the sensor-to-segment calibration asked for (app.choices.CALIBRATIONS; ProcessOptions.calibration)
    calibration: Mapped[str] = mapped_column(String(20), default=DEFAULT_CALIBRATION, server_default=DEFAULT_CALIBRATION)
    #: the knee-angle convention asked for (app.choices.ANGLE_CONVENTIONS; ProcessOptions.angle_method)
    angle_method: Mapped[str] = mapped_column(String(20), default=DEFAULT_ANGLE_CONVENTION,
                                              server_default=DEFAULT_ANGLE_CONVENTION)
    #: the cycles the clinician excluded (ProcessOptions.exclusions: ``[{"cycle", "knee", "reason", "by", "at"}]``); a
    #: job that has it (an empty list too) supersedes the session's earlier analyses; None: an ordinary processing
    cycle_exclusions: Mapped[list | None] = mapped_column(JSON, nullable=True)
    #: a failed job's message as a catalogue code and its values (app.pipeline.ingestion.messages), for any language
    error_code: Mapped[str | None] = mapped_column(String(60), nullable=True)
    error_params: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    analysis_id: Mapped[int | None] = mapped_column(Integer, nullable=True)  # no FK: analyses point back here
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    started_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    finished_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    #: the pipeline version the job runs (:data:`app.pipeline.session.PIPELINE_VERSION`); with the session it keys the work
    pipeline_version: Mapped[str] = mapped_column(String(40), default="", server_default="")
    #: when the job was last handed to the engine (the sweeper hands it again when it stays queued too long)
    dispatched_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    #: refreshed while a worker runs the job; a running job whose heartbeat is older than the lease is orphaned
    heartbeat_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)


class Analysis(Base):
    __tablename__ = "analyses"
    id: Mapped[int] = mapped_column(primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), index=True)
    job_id: Mapped[int] = mapped_column(ForeignKey("jobs.id", ondelete="CASCADE"), unique=True)
    filter: Mapped[str] = mapped_column(String(40))
    lang: Mapped[str] = mapped_column(String(2), default="es")
    accepted_cycles: Mapped[int] = mapped_column(Integer, default=0)
    warnings: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    #: the pipeline version and the session's ``files_version`` this analysis was computed from
    pipeline_version: Mapped[str] = mapped_column(String(40), default="", server_default="")
    files_version: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: the calibration and knee-angle convention it was computed with (its job's): two analyses differing in either
    #: are not compared or trended together, and only a Grood & Suntay one is the session's current result
    calibration: Mapped[str] = mapped_column(String(20), default=DEFAULT_CALIBRATION, server_default=DEFAULT_CALIBRATION)
    angle_method: Mapped[str] = mapped_column(String(20), default=DEFAULT_ANGLE_CONVENTION,
                                              server_default=DEFAULT_ANGLE_CONVENTION)
    #: set when a recording it was computed from was deleted or the facts it printed were corrected
    #: (:func:`app.store.analyses.supersede`): no longer served as the session's final report
    superseded_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    artefacts: Mapped[list["Artefact"]] = relationship(order_by="Artefact.id", cascade="all, delete-orphan")


class Interpretation(Base):
    """The clinician's interpretation of one analysis (issue 17 §3): a draft ``text`` until a clinician signs it
    (``signed_*``: who, their role then, when); signed, it is locked: changed only by an amendment
    (:class:`InterpretationAmendment`), which keeps the text it replaced.  :mod:`app.store.interpretations`."""

    __tablename__ = "interpretations"
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), index=True)
    analysis_id: Mapped[int] = mapped_column(ForeignKey("analyses.id", ondelete="CASCADE"), unique=True)
    text: Mapped[str] = mapped_column(Text, default="")
    #: who last saved the draft (a user's name or email, or an API token's label) and when
    updated_by: Mapped[str] = mapped_column(String(320), default="")
    updated_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    signed_by_user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"), nullable=True)
    signed_by: Mapped[str | None] = mapped_column(String(320), nullable=True)
    signed_role: Mapped[str | None] = mapped_column(String(20), nullable=True)
    signed_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)
    amendments: Mapped[list["InterpretationAmendment"]] = relationship(
        order_by="InterpretationAmendment.id", cascade="all, delete-orphan", lazy="selectin")


class InterpretationAmendment(Base):
    """One amendment of a signed interpretation: the text before and after, by whom (user, name, role), when, why."""

    __tablename__ = "interpretation_amendments"
    id: Mapped[int] = mapped_column(primary_key=True)
    interpretation_id: Mapped[int] = mapped_column(ForeignKey("interpretations.id", ondelete="CASCADE"), index=True)
    previous_text: Mapped[str] = mapped_column(Text)
    text: Mapped[str] = mapped_column(Text)
    reason: Mapped[str] = mapped_column(Text)
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"), nullable=True)
    by: Mapped[str] = mapped_column(String(320))
    role: Mapped[str] = mapped_column(String(20))
    at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)


class Artefact(Base):
    """One output file of an analysis: ``name`` (results.json, report.pdf, ...) and ``lang`` for the PDFs."""

    __tablename__ = "artefacts"
    __table_args__ = (UniqueConstraint("analysis_id", "name", "lang", name="uq_artefacts_analysis_name_lang"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    analysis_id: Mapped[int] = mapped_column(ForeignKey("analyses.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(40))
    lang: Mapped[str] = mapped_column(String(2), default="")
    media_type: Mapped[str] = mapped_column(String(100))
    sha256: Mapped[str] = mapped_column(ForeignKey("blobs.sha256"), index=True)  # indexed: blob reference counts
    size_bytes: Mapped[int] = mapped_column(Integer)


class BlobErasure(Base):
    """One stored file whose last reference went (:mod:`app.store.erasure`): the work item while ``pending``
    and, once ``erased`` or ``kept`` (referenced again, or still by another row), the record that survives the
    erasure — what (sha256, size), why, by whom, when; never the content.  No foreign keys: the rows it names
    are gone."""

    __tablename__ = "blob_erasures"
    id: Mapped[int] = mapped_column(primary_key=True)
    sha256: Mapped[str] = mapped_column(String(64), index=True)
    size_bytes: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: ``pending`` (marked, file still there), ``erased`` (row and bytes gone), ``kept`` (still referenced)
    state: Mapped[str] = mapped_column(String(10), default="pending", index=True)
    #: ``recording``, ``session``, ``patient``, ``retention``, ``orphan`` (a row or file no reference names)
    reason: Mapped[str] = mapped_column(String(20))
    clinic_id: Mapped[int | None] = mapped_column(Integer, nullable=True, index=True)
    patient_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    session_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: the audit event of the request or command that erased (its ``actor`` says who)
    audit_event_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    actor: Mapped[str] = mapped_column(String(320), default="")
    requested_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    done_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)


class AuditEvent(Base):
    """Who viewed, downloaded, exported or changed which patient's data, and the security events (logins, refused
    access, account changes) — append-only; ``app.web.audit``."""

    __tablename__ = "audit_events"
    id: Mapped[int] = mapped_column(primary_key=True)
    #: null for a security event no clinic can be named for (a login with an unknown email, a 401 without a token)
    clinic_id: Mapped[int | None] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True,
                                                  nullable=True)
    at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow, index=True)
    #: ``user`` (browser), ``token`` (hospital system) or ``anonymous`` (no valid credentials); the ids stay even
    #: if the account is deleted later
    actor_kind: Mapped[str] = mapped_column(String(10))
    user_id: Mapped[int | None] = mapped_column(Integer, nullable=True, index=True)
    token_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: a readable label of the actor at the time (user email or token label)
    actor: Mapped[str] = mapped_column(String(320), default="")
    #: ``list``, ``search``, ``view``, ``create``, ``upload``, ``delete``, ``download``, ``export``, ``process``
    action: Mapped[str] = mapped_column(String(20))
    patient_id: Mapped[int | None] = mapped_column(Integer, nullable=True, index=True)
    session_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: the method and path (e.g. ``GET /api/v1/sessions/3/report.pdf``)
    resource: Mapped[str] = mapped_column(String(300))
    client: Mapped[str] = mapped_column(String(64), default="")
    #: the answer's status code of a refusal (401, 403, 404, 429) or of the request; null for older events
    status: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: what changed or why it was refused, e.g. ``role clinician -> admin`` or ``wrong password`` (no secrets)
    detail: Mapped[str] = mapped_column(String(300), default="", server_default="")


class LoginAttempts(Base):
    """The login throttle's counters, one row per key (``app.web.throttle.LoginThrottle``): ``pair:<email> <address>``,
    ``email:<email>``, ``account:<email>|<clinic digest>`` or ``ip:<address>``.  Times are Unix seconds (floats), so that the one atomic ``UPDATE`` that
    reserves an attempt does its arithmetic in SQL alike on SQLite and PostgreSQL."""

    __tablename__ = "login_attempts"
    key: Mapped[str] = mapped_column(String(420), primary_key=True)
    #: the email of ``pair:`` and ``email:`` keys (an admin's unlock deletes them by it), null for ``ip:`` and
    #: ``account:`` keys (an unlock deletes its own clinic's ``account:`` key by its key)
    email: Mapped[str | None] = mapped_column(String(320), nullable=True, index=True)
    #: attempts reserved since the key was last reset (a success resets ``pair:`` and ``email:`` keys)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    #: the delay the last reservation imposed on the next attempt (doubles per attempt past the free ones)
    delay_s: Mapped[float] = mapped_column(Float, default=0.0)
    #: no attempt of this key before this time
    next_s: Mapped[float] = mapped_column(Float, default=0.0)
    #: the last reservation (a key idle for the policy's ``forget_s`` starts again from zero)
    last_s: Mapped[float] = mapped_column(Float, default=0.0)


class IdempotencyKey(Base):
    """A POST that created something, remembered under the caller's ``Idempotency-Key`` (``app.store.idempotency``):
    the same key again answers the same resource instead of creating another.  Only ids are kept (``resource_ids``),
    never the answer's body, so an erasure leaves no copy of a patient's data here."""

    __tablename__ = "idempotency_keys"
    __table_args__ = (UniqueConstraint("clinic_id", "key", name="uq_idempotency_clinic_key"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    key: Mapped[str] = mapped_column(String(200))
    #: sha256 of the method, the path and the request's body: the same key with another request is refused
    request_sha256: Mapped[str] = mapped_column(String(64))
    #: what was created: ``patient``, ``session``, ``upload`` or ``job``
    kind: Mapped[str] = mapped_column(String(20))
    resource_ids: Mapped[list] = mapped_column(JSON, default=list)
    status: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow, index=True)


class WebhookSubscription(Base):
    """Where a clinic wants to hear that a job finished or failed (``app.store.webhooks``): each delivery is signed
    with HMAC-SHA256 under ``secret`` (shown once, when the subscription is made; stored sealed under
    ``CHAKAMO_SECRET_KEY``, :mod:`app.store.sealed`).  ``kind`` ``fhir``: the operator's push of the clinic's reports
    to the hospital's FHIR server (``CHAKAMO_FHIR_PUSH_URL``; at most one per clinic, no secret: the server's token
    is a setting), made by the sender itself and never listed among the clinic's webhooks."""

    __tablename__ = "webhook_subscriptions"
    __table_args__ = (Index("uq_webhook_subscriptions_fhir_clinic", "clinic_id", unique=True,
                            sqlite_where=text("kind = 'fhir'"), postgresql_where=text("kind = 'fhir'")),)
    id: Mapped[int] = mapped_column(primary_key=True)
    clinic_id: Mapped[int] = mapped_column(ForeignKey("clinics.id", ondelete="CASCADE"), index=True)
    url: Mapped[str] = mapped_column(String(2000))
    #: space-separated event names (``job.done``, ``job.failed``)
    events: Mapped[str] = mapped_column(String(200))
    secret: Mapped[str] = mapped_column(String(100))
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    label: Mapped[str] = mapped_column(String(200), default="")
    #: ``webhook`` (a clinic's receiver) or ``fhir`` (the FHIR push, ``app.web.fhir_push``)
    kind: Mapped[str] = mapped_column(String(10), default="webhook", server_default="webhook")


class WebhookDelivery(Base):
    """One event for one subscription, and every attempt to deliver it: the audit trail of the webhooks."""

    __tablename__ = "webhook_deliveries"
    #: one delivery per subscription, job and event: a job's end, and for the FHIR push its retraction
    #: (``app.store.webhooks``)
    __table_args__ = (UniqueConstraint("subscription_id", "job_id", "event", name="uq_webhook_delivery_job"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    subscription_id: Mapped[int] = mapped_column(ForeignKey("webhook_subscriptions.id", ondelete="CASCADE"),
                                                 index=True)
    clinic_id: Mapped[int] = mapped_column(Integer, index=True)
    job_id: Mapped[int] = mapped_column(Integer)
    event: Mapped[str] = mapped_column(String(40))
    payload: Mapped[dict] = mapped_column(JSON)
    #: ``pending`` (to send, at ``next_attempt_at``), ``delivered`` (a 2xx answer) or ``failed`` (attempts used up)
    state: Mapped[str] = mapped_column(String(10), default="pending", index=True)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    next_attempt_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    last_status: Mapped[int | None] = mapped_column(Integer, nullable=True)
    #: the code of the last failed attempt (``app.web.webhooks``' codes, rendered in es/en/pt); "" when none
    last_error: Mapped[str] = mapped_column(String(300), default="")
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utcnow)
    delivered_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime, nullable=True)


__all__ = ["ROLES", "AuditEvent", "JOB_STATES", "Analysis", "ApiToken", "Artefact", "Base", "Blob", "BlobErasure",
           "BrowserSession", "Clinic", "IdempotencyKey", "Job", "KneeSession", "LoginAttempts", "Patient", "Recording", "User", "WebhookDelivery", "WebhookSubscription", "utcnow"]
