"""The ``chakamo`` command line.

Subcommands
-----------
``chakamo demo --out DIR``
    Simulate a realistic session with known truth, write it as MetaBase files, process it through the
    same code path as real data and print the accuracy against the truth.
``chakamo process SESSION_DIR --out DIR [--filter NAME] [--lang es|en|pt] [--side right|left] [--task NAME]``
    Process one recorded session into ``results.json`` and the reports (``--task``: the motor task recorded).
``chakamo view OUT_DIR [--host 127.0.0.1] [--port 8080] [--lang es|en|pt]``
    Serve the 3D femur-tibia animation of a processed session live (viser), until Ctrl-C.
``chakamo walk FILE [--format iez|npz] [--sensor 1|2] [--method NAME] [--json OUT] [--plot OUT.svg]``
    Foot-mounted pedestrian dead reckoning: trajectory, strides and metrics.
``chakamo markov FILE --out DIR [--method auto|mjls|kf|sme|smea] [--zeta G] [--joint-axis x|y|z] [--still S]``
    Markovian Kalman filters on a research CSV of several segment IMUs (format in ``app/research/markov.py``).
``chakamo serve`` / ``clinics create`` / ``users create`` / ``tokens create``
    The web application and its set-up (``app/cli/admin.py``).
``chakamo tokens list|revoke`` / ``users deactivate|set-password``
    Offboarding: list and revoke API tokens, deactivate users, reset passwords (``app/cli/admin.py``).
``chakamo patients|sessions correct|erase`` / ``retention [--days N] [--apply]``
    Operator corrections and erasures of patient data, and the retention policy (``app/cli/records.py``).
``chakamo migrate`` / ``worker`` / ``reprocess --filter NAME --since DATE``
    The scaled-out deployment: schema upgrade, a Celery worker, a cohort queued again (``app/cli/ops.py``).

The parser is built from the command groups below (:data:`GROUPS`: each module has ``COMMANDS``,
``add_parsers(sub)`` and ``run(args)``), whose choices all come from :mod:`app.choices`; nothing heavier than
the option lists is imported until a command runs, so ``chakamo --help`` starts fast.

Errors a user can cause end with a one-line message on stderr and exit status 2; nothing is written.  Every
sentence of ``chakamo``'s own, argparse's usage errors and ``--help`` frame included, speaks ``--lang`` when the
command line gives it, English otherwise (:mod:`app.cli.language`).
"""

from __future__ import annotations

import time

_T0 = time.perf_counter()  # the start of `total` in CHAKAMO_TIMINGS (app.pipeline.timings)

import sys  # noqa: E402

from app.cli import admin, language, ops, records, research, session  # noqa: E402
from estimators import __version__  # noqa: E402

#: the command groups, in the order ``chakamo --help`` lists them
GROUPS = (session, research, admin, records, ops)


def _build_parser(lang: str | None = None) -> language.Parser:
    """The ``chakamo`` parser; argparse's own sentences (usage errors, the help frame) in ``lang``."""
    parser = language.Parser(prog="chakamo", lang=lang, description="Clinical 3D knee kinematics from two IMUs.")
    parser.add_argument("--version", action="version", version=f"chakamo {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in GROUPS:
        group.add_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = _build_parser(language.requested(argv)).parse_args(argv)
    group = next(g for g in GROUPS if args.command in g.COMMANDS)
    from app.store.errors import DomainError  # the data layer's refusals (cheap: no database stack)

    try:
        return group.run(args)
    except (ValueError, OSError, DomainError) as exc:  # a file problem, a refusal: what to do, in --lang if given
        lang = getattr(args, "lang", None) or "en"
        text = exc.message(lang) if callable(getattr(exc, "message", None)) else str(exc)
        print(language.error_line(f"chakamo {args.command}", text, lang), end="", file=sys.stderr)
        return 2
    finally:
        from app.pipeline import timings

        timings.report("total", time.perf_counter() - _T0, time.process_time())
        if timings.enabled():
            import resource

            timings.report_process("main", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                                   time.process_time())


#: commands that end the process when done: nothing of theirs needs the interpreter's teardown
_EXIT_FAST = frozenset({"demo", "process"})


def console() -> None:
    """The ``chakamo`` console script: :func:`main`, then exit.  After ``demo`` and ``process`` (every file
    written, closed and renamed in place by then) the process ends without the interpreter's teardown, which
    spends ~0.9 s of CPU unloading numba and llvmlite (``benchmarks/cold.py``); the other commands (servers,
    workers) exit normally."""
    argv = sys.argv[1:]
    rc = main(argv)
    if argv and argv[0] in _EXIT_FAST:
        import logging
        import os

        sys.stdout.flush()
        sys.stderr.flush()
        logging.shutdown()
        os._exit(rc)
    raise SystemExit(rc)


if __name__ == "__main__":  # pragma: no cover
    console()
