"""Operator commands that correct and erase patient data (``chakamo patients``, ``sessions``, ``retention``).

``chakamo patients correct --clinic NAME ID --set FIELD=VALUE [--set ...]``
    Correct a patient (fields as ``PATCH /api/v1/patients/{id}``: external_id, side, name, birth_date, sex,
    height_cm, mass_kg, notes; an empty VALUE clears an optional field).  A change of what the reports print
    supersedes the patient's analyses.
``chakamo patients erase --clinic NAME ID --confirm EXTERNAL_ID``
    Erase the patient with every session, recording, analysis, report and the stored files no other row
    names.  ``--confirm`` must repeat the patient's external id: the explicit confirmation a cascade needs.
``chakamo sessions correct --clinic NAME ID --set FIELD=VALUE [...]``
    Correct a session (date, task, step_height_m, professional, notes); its analyses are superseded.
``chakamo sessions erase --clinic NAME ID --confirm EXTERNAL_ID``
    Erase one session and everything under it (``--confirm``: its patient's external id).
``chakamo retention [--days N] [--apply]``
    The retention policy (:mod:`app.store.retention`; ``--days`` defaults to ``CHAKAMO_RETENTION_DAYS``): without
    ``--apply`` a dry run listing the sessions due; with it they are erased, then the erasure sweep removes what
    no row names (:func:`app.store.erasure.sweep`).

Every change is audited as the operator (actor kind ``operator``, "chakamo CLI (<os user>)") through
:func:`app.web.audit.record_operator`, in the transaction that makes it; the erasures leave their
``blob_erasures`` records (hash, size, when; never the content).  The same rules as the API apply (the data
layer's functions are the same): refused while a job of the session is queued or running, another clinic's ids
are unknown.  Errors are ``ValueError`` with one sentence (:class:`app.cli.admin.CliError`: a catalogue entry), or
the data layer's own :class:`app.store.errors.DomainError` as it is; the CLI prints either in ``--lang``, exit
status 2; what the commands print is in ``--lang`` too (English when not given).
"""

from __future__ import annotations

import argparse
import datetime as dt
import getpass
from typing import TYPE_CHECKING, Any

from app.choices import LANGUAGE_NAMES
from app.cli.admin import CliError, _say

if TYPE_CHECKING:
    from app.settings import Settings

COMMANDS = ("patients", "sessions", "retention")


def _actor() -> str:
    try:
        who = getpass.getuser()
    except (KeyError, OSError):  # no user name in a container
        who = "unknown"
    return f"chakamo CLI ({who})"


#: how a ``--set`` value is read, per field (the rest are text); the data layer checks ranges and choices
_DATES = ("birth_date", "date")
_NUMBERS = ("height_cm", "mass_kg", "step_height_m")


def _parse_sets(pairs: list[str], fields: tuple[str, ...]) -> dict[str, Any]:
    """``FIELD=VALUE`` pairs as column values (dates ISO 8601, numbers with a point or a comma); an empty value
    is null."""
    values: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key:
            raise CliError("cli.set_not_pair", pair=pair)
        if key not in fields:
            raise CliError("cli.set_field", field=key, fields=", ".join(fields))
        try:
            if not value:
                values[key] = None
            elif key in _DATES:
                values[key] = dt.date.fromisoformat(value)
            elif key in _NUMBERS:
                values[key] = float(value.replace(",", "."))
            else:
                values[key] = value
        except ValueError:
            raise CliError("cli.set_not_date" if key in _DATES else "cli.set_not_number", field=key,
                           value=value) from None
    if not values:
        raise CliError("cli.set_nothing")
    return values


def _clinic_id(db, clinic: str) -> int:
    from app.cli.admin import _clinic

    return _clinic(db, clinic).id


def correct(settings: Settings | None, kind: str, *, clinic: str, row_id: int, sets: list[str]) -> list[str]:
    """Correct patient or session ``row_id`` (``kind``) of ``clinic``; returns the fields that changed."""
    from app.cli.admin import _session
    from app.store import patients, sessions
    from app.web.audit import record_operator

    values = _parse_sets(sets, patients.CORRECTABLE_FIELDS if kind == "patient"
                         else sessions.PROCESSED_FIELDS + sessions.ORDER_FIELDS)
    with _session(settings) as db:
        cid = _clinic_id(db, clinic)
        if kind == "patient":
            row, changed, _ = patients.correct_patient(db, cid, row_id, values)
            pid, sid = row.id, None
        else:
            row, changed, _ = sessions.correct_session(db, cid, row_id, values)
            pid, sid = row.patient_id, row.id
        if changed:
            record_operator(db, clinic_id=cid, action="update", actor=_actor(), patient_id=pid, session_id=sid,
                            resource=f"chakamo {kind}s correct {row_id} ({', '.join(changed)})")
        return changed


def erase(settings: Settings | None, kind: str, *, clinic: str, row_id: int, confirm: str) -> dict:
    """Erase patient or session ``row_id`` of ``clinic`` after ``confirm`` matched its patient's external id;
    returns ``{"sessions": n, "files_erased": n, "files_kept": n}``."""
    from app.cli.admin import _database
    from app.store import erasure, patients, sessions
    from app.store.blobs import open_storage
    from app.settings import get_settings
    from app.web.audit import record_operator

    settings = settings or get_settings(require_key=False)  # no secret key used here
    database = _database(settings)
    try:
        with database.session() as db:
            cid = _clinic_id(db, clinic)
            if kind == "patient":
                external_id = patients.clinic_patient(db, cid, row_id).external_id
            else:
                external_id = sessions.clinic_session(db, cid, row_id).patient.external_id
            if confirm.strip() != external_id:
                raise CliError("cli.erase_confirm", confirm=confirm)
            if kind == "patient":
                session_ids, shas = patients.delete_patient(db, cid, row_id)
                pid, sid = row_id, None
            else:
                pid, shas = sessions.delete_session(db, cid, row_id)
                session_ids, sid = [row_id], row_id
            event = record_operator(db, clinic_id=cid, action="delete", actor=_actor(), patient_id=pid,
                                    session_id=sid, resource=f"chakamo {kind}s erase {row_id}")
            ids = erasure.mark(db, shas, reason=kind, actor=event.actor, clinic_id=cid, patient_id=pid,
                               session_id=sid, audit_event_id=event.id)
        counts = erasure.erase_pending(database, open_storage(settings), ids)
        return {"sessions": len(session_ids), "files_erased": counts.erased, "files_kept": counts.kept}
    finally:
        database.dispose()


def retention(settings: Settings | None, *, days: int | None = None, apply: bool = False,
              now: dt.datetime | None = None):
    """The retention policy's dry run or application (module docstring); returns its
    :class:`app.store.retention.RetentionReport` (``apply``: with the erasure sweep's count in ``swept_files``)."""
    from app.cli.admin import _database
    from app.store.blobs import open_storage
    from app.store.erasure import sweep
    from app.store.models import utcnow
    from app.store.retention import apply_retention
    from app.settings import get_settings
    from app.web.housekeeping import operator_recorder

    settings = settings or get_settings(require_key=False)  # no secret key used here
    days = settings.retention_days if days is None else days
    if days <= 0:
        raise CliError("cli.retention_off")
    database = _database(settings)
    try:
        store = open_storage(settings)
        report = apply_retention(database, store, days, now=now or utcnow(), dry_run=not apply,
                                 record=operator_recorder(f"{_actor()}: retention {days} days"))
        report.swept_files = sweep(database, store).erased if apply else 0
        return report
    finally:
        database.dispose()


def add_parsers(sub) -> None:
    """Register ``patients``, ``sessions`` and ``retention`` on the ``chakamo`` subparsers."""
    groups = []
    for kind in ("patient", "session"):
        group = sub.add_parser(f"{kind}s", help=f"correct or erase a {kind} (operator)")
        actions = group.add_subparsers(dest="action", required=True)
        groups.append(actions)
        fix = actions.add_parser("correct", help=f"correct a {kind}'s fields (audited)")
        fix.add_argument("--clinic", required=True, metavar="NAME")
        fix.add_argument("row_id", type=int, metavar="ID")
        fix.add_argument("--set", dest="sets", action="append", default=[], metavar="FIELD=VALUE",
                         help="a field to correct (repeat; an empty VALUE clears it)")
        rm = actions.add_parser("erase", help=f"erase a {kind} and everything under it, files included")
        rm.add_argument("--clinic", required=True, metavar="NAME")
        rm.add_argument("row_id", type=int, metavar="ID")
        rm.add_argument("--confirm", required=True, metavar="EXTERNAL_ID",
                        help="the patient's external id, repeated: the confirmation the erasure needs")
    ret = sub.add_parser("retention", help="list (dry run) or erase the sessions past the retention period")
    ret.add_argument("--days", type=int, default=None, help="(default: CHAKAMO_RETENTION_DAYS)")
    ret.add_argument("--apply", action="store_true", help="erase them (without: a dry run)")
    for parser in (*[p for g in groups for p in g.choices.values()], ret):   # their output and errors in --lang
        parser.add_argument("--lang", choices=LANGUAGE_NAMES, default=None,
                            help="language of the messages (default: English)")


def run(args: argparse.Namespace) -> int:
    """Carry out a parsed ``patients`` / ``sessions`` / ``retention`` command."""
    if args.command == "retention":
        r = retention(None, days=args.days, apply=args.apply)
        print(_say(args.lang, "cli.retention_erased" if args.apply else "cli.retention_due", days=r.days,
                   now=f"{r.now:%Y-%m-%d %H:%M}", n=len(r.due)))
        for d in r.due:
            print(_say(args.lang, "cli.retention_session", session=d.session_id, clinic=d.clinic_id,
                       patient=d.patient_id, last=f"{d.last_activity:%Y-%m-%d}"))
        if args.apply:
            print(_say(args.lang, "cli.retention_files", erased=r.erased_files, kept=r.kept_files,
                       swept=r.swept_files))
        return 0
    kind = args.command[:-1]
    named = _say(args.lang, f"cli.kind_{kind}")
    if args.action == "correct":
        changed = correct(None, kind, clinic=args.clinic, row_id=args.row_id, sets=args.sets)
        print(_say(args.lang, "cli.corrected", kind=named, id=args.row_id, fields=", ".join(changed)) if changed
              else _say(args.lang, "cli.unchanged", kind=named, id=args.row_id))
    else:
        out = erase(None, kind, clinic=args.clinic, row_id=args.row_id, confirm=args.confirm)
        print(_say(args.lang, f"cli.erased_{kind}", id=args.row_id, sessions=out["sessions"],
                   erased=out["files_erased"], kept=out["files_kept"]))
    return 0


__all__ = ["COMMANDS", "add_parsers", "correct", "erase", "retention", "run"]
