"""Asking for a session to be processed: :func:`enqueue` inserts a ``queued`` job after checking that the
session may be processed now; :func:`hand_over` tells the engine.

Used by ``POST /sessions/{id}/process`` and by ``chakamo reprocess`` (:mod:`app.jobs.reprocess`) alike.
The rules, in order: a session with a queued or running job is refused (:class:`app.store.sessions.Busy`);
a stale ingestion check (files changed since) is redone first, holding no transaction
(:meth:`app.store.checks.IngestionChecker.ensure_fresh`); then, with the session's row locked, busy is
checked again and files that do not pass the check are refused (:class:`NotReady`); optionally an analysis
that already exists for this filter, language, pipeline version, files and processing choices (:data:`CHOICES`:
heading, side, involved knee, calibration, angle convention) is refused (:class:`UpToDate`: what makes a cohort
run idempotent).  :func:`previous_choices` gives the choices a session was last processed with, so a cohort
run asks for them again instead of the defaults.  After the insert a job queued by a concurrent request (SQLite has no
row locks) is detected and refused too (``Busy``: the caller's transaction must be rolled back, which
leaving the ``Database.session`` block by the exception does).

Cycle exclusions (the clinician's choice of cycles, :mod:`app.pipeline.exclusions`) are tied to the analysis they
were chosen on: a request that names them must name that analysis (``based_on``), the session's current one (its
latest, not superseded, of the current files and pipeline version; else :class:`StaleChoice`, 409), and the new
job takes that analysis' options (filter, heading, side, involved knee, calibration, angle convention) whatever the
request says; an entry unchanged since that analysis keeps who excluded it and when.  An ordinary processing of a
session whose current analysis has exclusions carries them over (they still name the same detected cycles: same
files and pipeline), so that re-running never silently includes a cycle the clinician left out; when the files,
facts or pipeline changed since, they are not carried over (the cycles may be others) and the job's log says so.

The job row must be committed before the engine hears of it, so a crash between the two loses nothing (the
engines' sweepers resubmit queued jobs): the caller commits, then calls :func:`hand_over`.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.choices import DEFAULT_ANGLE_CONVENTION, DEFAULT_CALIBRATION, DEFAULT_HEADING
from app.jobs.work import JobRunner
from app.pipeline.session import PIPELINE_VERSION
from app.store.analyses import latest_analysis
from app.store.checks import IngestionChecker
from app.store.errors import Conflict, Invalid
from app.store.models import Analysis, Job, KneeSession
from app.store.sessions import Busy, active_job_id, clinic_session, ingestion_fresh, ready, refuse_while_processing

log = logging.getLogger("chakamo.jobs")


class NotReady(Conflict):
    """The session's files do not pass the ingestion check; ``reason`` is the check's stored message (its code,
    params and English text: :func:`app.pipeline.service_messages.item`, rendered in the reader's language; a
    plain sentence for a check stored before codes were), or None."""

    def __init__(self, reason: dict | str | None) -> None:
        super().__init__(code="store.not_ready", reason=reason or {"code": "session.no_files_yet", "params": {}})
        self.reason = reason


#: the processing choices a job carries besides filter and language (ProcessOptions' heading, side, involved,
#: calibration, angle_method): an analysis is current only for the same ones
CHOICES = ("heading", "side", "involved", "calibration", "angle_method")


class UpToDate(Conflict):
    """An analysis with the same filter, language and choices exists for this pipeline version and these files."""

    def __init__(self, analysis_id: int) -> None:
        super().__init__(code="store.up_to_date", analysis_id=analysis_id, version=PIPELINE_VERSION)
        self.analysis_id = analysis_id


class StaleChoice(Conflict):
    """Cycles chosen on an analysis that is not the session's current one (a newer one, files or facts changed)."""

    def __init__(self, analysis_id: int, session_id: int) -> None:
        super().__init__(code="store.exclusions_stale", analysis_id=analysis_id, session_id=session_id)


def _current_choice(db: Session, session: KneeSession,
                    based_on: int | None = None) -> tuple[Analysis | None, Job | None]:
    """The analysis cycles are chosen on and its job when that analysis is current (not superseded, of the current
    files and pipeline version: its cycle numbers still name the same detected cycles), else ``(analysis, None)``.
    ``based_on``: the analysis the clinician chose on (any of the session's conventions: a ZYX analysis is as
    current as the Grood & Suntay one of the same files); None: the session's latest
    (:func:`app.store.analyses.latest_analysis`), whose exclusions an ordinary processing may carry over."""
    if based_on is not None:
        chosen = db.get(Analysis, based_on)
        chosen = chosen if chosen is not None and chosen.session_id == session.id else None
    else:
        chosen = latest_analysis(db, session.id)
    if chosen is None or chosen.job_id is None:
        return chosen, None
    if (chosen.superseded_at is not None or chosen.files_version != session.files_version
            or chosen.pipeline_version != PIPELINE_VERSION):
        return chosen, None
    return chosen, db.get(Job, chosen.job_id)


def current_analysis(db: Session, session: KneeSession, filter_name: str, lang: str, *,
                     heading: str = DEFAULT_HEADING, side: str | None = None, involved: str | None = None,
                     calibration: str = DEFAULT_CALIBRATION, angle_method: str = DEFAULT_ANGLE_CONVENTION) -> int | None:
    """The id of an analysis of ``session``'s current files with this filter, language, pipeline version and
    choices (:data:`CHOICES`, as its job asked for them), or None."""
    chosen = {"heading": heading, "side": side, "involved": involved, "calibration": calibration,
              "angle_method": angle_method}
    return db.scalar(select(Analysis.id).join(Job, Job.id == Analysis.job_id).where(
        Analysis.session_id == session.id, Analysis.filter == filter_name, Analysis.lang == lang,
        Analysis.pipeline_version == PIPELINE_VERSION, Analysis.files_version == session.files_version,
        *(getattr(Job, k).is_not_distinct_from(chosen[k]) for k in CHOICES)).limit(1))


def previous_choices(db: Session, session_id: int) -> dict[str, str | None]:
    """The :data:`CHOICES` of the job behind the session's current analysis
    (:func:`app.store.analyses.latest_analysis`), else of its latest job; empty when it has none (the defaults)."""
    analysis = latest_analysis(db, session_id)
    job = db.get(Job, analysis.job_id) if analysis is not None else \
        db.scalar(select(Job).where(Job.session_id == session_id).order_by(Job.id.desc()).limit(1))
    return {} if job is None else {k: getattr(job, k) for k in CHOICES}


def enqueue(db: Session, clinic_id: int, session_id: int, *, filter_name: str, lang: str,
            checker: IngestionChecker, log_lines: Sequence[str] = (), unless_current: bool = False,
            heading: str = DEFAULT_HEADING, side: str | None = None, involved: str | None = None,
            calibration: str = DEFAULT_CALIBRATION, angle_method: str = DEFAULT_ANGLE_CONVENTION,
            cycle_exclusions: tuple[list[dict], str] | None = None, based_on: int | None = None) -> Job:
    """Insert (and flush, not commit) a queued job of session ``session_id`` of clinic ``clinic_id`` (module
    docstring for the rules); raises :class:`app.store.errors.NotFound`, :class:`Busy`, :class:`NotReady`
    or (with ``unless_current``) :class:`UpToDate`.  ``db`` may be rolled back on the way (the check).  ``side``:
    the side the clinician chose over the files' (:attr:`app.pipeline.session.ProcessOptions.side`), or None;
    ``involved``: the involved knee of a two-knee session (``ProcessOptions.involved``), or None (the patient's);
    ``calibration`` / ``angle_method``: ``ProcessOptions.calibration`` / ``.angle_method``;
    ``cycle_exclusions``: the cycles the clinician excluded (``[{"cycle", "knee", "reason"}]``) and who did, kept
    on the job with the time (:func:`exclusion_records`), or None; ``based_on``: the analysis they were chosen on,
    required with them (module docstring: :class:`StaleChoice`)."""
    if cycle_exclusions is not None and based_on is None:
        raise Invalid(code="store.exclusions_need_base")
    what = "process"
    session = clinic_session(db, clinic_id, session_id)
    refuse_while_processing(db, session.id, what)
    checker.ensure_fresh(db, session)
    session = clinic_session(db, clinic_id, session_id, lock=True)
    refuse_while_processing(db, session.id, what)
    if not ready(session):
        stored = session.ingestion if ingestion_fresh(session) else {}
        raise NotReady(stored.get("error_item") or stored.get("error"))
    if unless_current and (done := current_analysis(db, session, filter_name, lang, heading=heading, side=side,
                                                    involved=involved, calibration=calibration,
                                                    angle_method=angle_method)) is not None:
        raise UpToDate(done)
    latest, base = _current_choice(db, session, based_on if cycle_exclusions is not None else None)
    records, notes = None, []
    if cycle_exclusions is not None:
        if latest is None or base is None:
            raise StaleChoice(based_on, session.id)
        filter_name, heading, side, involved = base.filter, base.heading, base.side, base.involved
        calibration, angle_method = base.calibration, base.angle_method
        records = exclusion_records(*cycle_exclusions, earlier=base.cycle_exclusions)
    elif base is not None and base.cycle_exclusions:
        records = [dict(e) for e in base.cycle_exclusions]
        notes.append(f"cycles excluded on analysis {latest.id} carried over: {_named(records)}")
    elif latest is not None and latest.job_id is not None and (was := db.get(Job, latest.job_id)).cycle_exclusions:
        notes.append(f"cycles excluded on analysis {latest.id} ({_named(was.cycle_exclusions)}) not carried over: "
                     "the files, facts or pipeline changed since; choose them again on the new analysis")
    job = Job(clinic_id=session.clinic_id, session_id=session.id, filter=filter_name, lang=lang, heading=heading, side=side,
              involved=involved, calibration=calibration, angle_method=angle_method, log=[*log_lines, *notes],
              stage="queued",
              cycle_exclusions=records,
              pipeline_version=PIPELINE_VERSION)
    db.add(job)
    db.flush()
    other = active_job_id(db, session.id, other_than=job.id)
    if other is not None:  # another request queued one at the same moment (SQLite has no row locks)
        raise Busy(session.id, other, what)
    return job


def exclusion_records(items: Sequence[Mapping], by: str, earlier: Sequence[Mapping] | None = None) -> list[dict]:
    """``Job.cycle_exclusions``: each cycle ``{"cycle", "knee", "reason"}`` of ``items`` recorded as excluded by ``by``
    now (:class:`app.pipeline.exclusions.CycleExclusion`; one entry per knee and cycle); an entry of ``earlier``
    (the base analysis' job) with the same cycle, knee and reason keeps its own ``by`` and ``at``."""
    from app.pipeline.exclusions import CycleExclusion, normalised, now_iso

    at = now_iso()
    kept = {(int(e["cycle"]), e.get("knee"), (e.get("reason") or "").strip()): e for e in earlier or ()}
    out = []
    for x in items:
        c = CycleExclusion(int(x["cycle"]), x.get("knee"), x.get("reason") or "", by, at)
        e = kept.get((c.cycle, c.knee, c.reason))
        out.append(CycleExclusion(c.cycle, c.knee, c.reason, e["by"], e["at"]) if e else c)
    return [e.to_dict() for e in normalised(out)]


def _named(records: Sequence[Mapping]) -> str:
    return ", ".join(f"{e['knee'] + ':' if e.get('knee') else ''}{e['cycle']}" for e in records) or "none"


def hand_over(runner: JobRunner, job_id: int) -> None:
    """Tell the engine of committed job ``job_id``; if it cannot hear now, its sweeper hands it over later."""
    try:
        runner.submit(job_id)
    except Exception:  # noqa: BLE001 — the job is committed: the engine's sweeper hands it over later
        log.warning("job %s queued but not handed to the engine now; the sweeper will", job_id, exc_info=True)


__all__ = ["CHOICES", "NotReady", "StaleChoice", "UpToDate", "current_analysis", "enqueue", "exclusion_records",
           "hand_over", "previous_choices"]
