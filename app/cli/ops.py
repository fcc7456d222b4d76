"""Operations commands of the scaled-out deployment (``chakamo migrate``, ``worker``, ``reprocess``).

``chakamo migrate [--lang es|en|pt]``
    Upgrade the database (``DATABASE_URL``) to the newest schema and exit: run it once before starting the
    API servers and workers of a new release (``docker/compose.yaml`` has it as a one-shot service), so that
    several processes never race to migrate.
``chakamo worker [--concurrency N] [--loglevel INFO] [--lang es|en|pt]``
    A Celery worker (``CHAKAMO_JOB_BACKEND=celery``, ``CHAKAMO_BROKER_URL``) running the processing jobs of
    every API server on this database (:mod:`app.jobs.celery_engine`); ``N`` processes (default ``CHAKAMO_WORKERS``).
    SIGTERM finishes the running jobs first; any number of workers on any number of machines sharing
    ``CHAKAMO_DATA_DIR`` (the blob store) and the database.
``chakamo reprocess --filter NAME --since YYYY-MM-DD [--clinic NAME] [--lang es|en|pt] [--force]``
    Queue a cohort for processing with another filter or a new pipeline version (:mod:`app.jobs.reprocess`);
    prints one line per session and what was done, idempotent (a second run queues nothing new).

Errors the user can fix raise ``ValueError`` with one sentence (the CLI prints it in ``--lang`` and exits with
status 2); the start-up lines an operator sees speak ``--lang`` too (English when not given).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys

from app import choices

COMMANDS = ("migrate", "worker", "reprocess")


def _date(text: str) -> dt.date:
    """``--since``: an ISO date (refused in the language of the command line: :mod:`app.cli.language`)."""
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        from app.cli.language import say

        raise argparse.ArgumentTypeError(say("cli.not_a_date", value=text)) from None


def add_parsers(sub) -> None:
    """Register ``migrate``, ``worker`` and ``reprocess`` on the ``chakamo`` subparsers."""
    migrate = sub.add_parser("migrate", help="upgrade the database schema to this release and exit")
    worker = sub.add_parser("worker", help="run a Celery worker for the processing jobs (CHAKAMO_JOB_BACKEND=celery)")
    for parser in (migrate, worker):   # their start-up lines and errors in --lang
        parser.add_argument("--lang", choices=choices.LANGUAGE_NAMES, default=None,
                            help="language of the messages (default: English)")
    worker.add_argument("--concurrency", type=int, default=None, metavar="N",
                        help="worker processes (default: CHAKAMO_WORKERS)")
    worker.add_argument("--loglevel", default="INFO", choices=("DEBUG", "INFO", "WARNING", "ERROR"))
    rep = sub.add_parser("reprocess", help="queue every session since a date for processing with a filter")
    rep.add_argument("--filter", required=True, choices=choices.FILTER_NAMES, help="orientation filter")
    rep.add_argument("--since", required=True, type=_date, metavar="YYYY-MM-DD", help="first session date")
    rep.add_argument("--clinic", default=None, metavar="NAME", help="only this clinic's sessions (default: all)")
    rep.add_argument("--lang", choices=choices.LANGUAGE_NAMES, default=None,
                     help=f"language of the reports and of the messages (default: reports in "
                          f"{choices.DEFAULT_LANGUAGE}, messages in English)")
    rep.add_argument("--force", action="store_true",
                     help="queue sessions already analysed by this pipeline version with this filter too")


def run(args: argparse.Namespace) -> int:
    """Carry out a parsed ``migrate`` / ``worker`` / ``reprocess`` command."""
    from app.cli.admin import CliError
    from app.cli.language import say
    from app.settings import get_settings

    settings = get_settings()
    if args.command == "migrate":
        from app.store.database import Database

        settings.data_dir.mkdir(parents=True, exist_ok=True)
        db = Database(settings.db_url)
        try:
            db.migrate(settings.sealing_key)
        finally:
            db.dispose()
        print(say("cli.migrated", args.lang, url=db.engine.url.render_as_string(hide_password=True)))
    elif args.command == "worker":
        if settings.job_backend != "celery":   # run_worker's own refusal, before celery is imported, in --lang
            raise CliError("cli.worker_needs_celery")
        if args.concurrency is not None and args.concurrency < 1:
            raise CliError("cli.concurrency_min")
        from app.jobs.celery_engine import QUEUE, run_worker

        print(say("cli.worker_started", args.lang, n=args.concurrency or settings.workers, queue=QUEUE),
              file=sys.stderr, flush=True)
        run_worker(settings, args.concurrency, args.loglevel)
    elif args.command == "reprocess":
        _reprocess(settings, args)
    return 0


def _reprocess(settings, args: argparse.Namespace) -> None:
    """``chakamo reprocess``: the table of outcomes and the hand-over, in ``--lang`` (English when not given)."""
    from app.jobs.reprocess import STATUSES, reprocess
    from app.pipeline.service_messages import render_item
    from app.web.messages import render

    lang = args.lang or "en"
    outcomes, summary = reprocess(settings, filter_name=args.filter, since=args.since, clinic=args.clinic,
                                  lang=args.lang or choices.DEFAULT_LANGUAGE, force=args.force)
    words = dict(zip(STATUSES, render("cli.reprocess_statuses", lang).split("|")))
    for o in outcomes:
        job = render("cli.reprocess_job", lang, id=o.job_id) if o.job_id is not None else ""
        note = render_item(o.note, lang) if o.note else ""
        print(f"{o.session_id:>6}  {o.patient:<20.20}  {o.date.isoformat()}  {words[o.status]:<9}  {job:<12}  "
              f"{note}".rstrip())
    counts = ", ".join(f"{sum(o.status == s for o in outcomes)} {words[s]}" for s in STATUSES)
    print(render("cli.reprocess_counts", lang, n=len(outcomes), counts=counts, summary=render_item(summary, lang)))


__all__ = ["COMMANDS", "add_parsers", "run"]
