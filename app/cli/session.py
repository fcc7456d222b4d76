"""Session commands: ``chakamo demo``, ``process`` and ``view``.

``chakamo demo --out DIR``
    Simulate a realistic session with known truth, write it as MetaBase files, process it through the
    same code path as real data and print the accuracy against the truth.
``chakamo process SESSION_DIR --out DIR [--filter NAME] [--lang es|en|pt] [--side right|left] [--task NAME] [--involved right|left] [--compare-with RESULTS_JSON] ...``
    Process one recorded session into ``results.json`` and the reports (``--task``: the motor task recorded).
``chakamo view OUT_DIR [--host 127.0.0.1] [--port 8080] [--lang es|en|pt]``
    Serve the 3D femur-tibia animation of a processed session live (viser), until Ctrl-C.

Every list of choices is :mod:`app.choices`; the pipeline is imported only when a command runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from app import choices

COMMANDS = ("demo", "process", "view")


def _stage(lang: str | None, stage: str) -> str:
    """A pipeline stage's name (``"read"``, ``"orientation thigh"``, ``"right knee"``…) in ``lang``
    (:data:`app.web.messages.CATALOGUE`'s ``cli.stage_*``, its words joined by ``_`` as ``stageText`` of
    static/views/wizard.js joins them; a stage without an entry as it is)."""
    from app.cli.admin import _say
    from app.web.messages import CATALOGUE

    side, _, rest = stage.partition(" ")
    if side in ("right", "left") and rest:
        return _say(lang, f"cli.stage_{side}", stage=_stage(lang, rest))
    code = f"cli.stage_{stage.replace(' ', '_')}"
    return _say(lang, code) if code in CATALOGUE else stage


def _progress(lang: str | None):
    """``process``'s progress callback: ``[ 30 %] segments`` on stderr, the stage in ``lang``."""

    def say(stage: str, fraction: float) -> None:
        print(f"[{100 * fraction:3.0f} %] {_stage(lang, stage)}", file=sys.stderr, flush=True)

    return say


def add_parsers(sub) -> None:
    """Register ``demo``, ``process`` and ``view`` on the ``chakamo`` subparsers."""
    demo = sub.add_parser("demo", help="simulate a session with known truth, process it, print the accuracy")
    demo.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default: out/demo)")
    demo.add_argument("--seed", type=int, default=7, help="random seed of the simulated session (default: 7)")
    demo.add_argument("--side", choices=choices.SIDE_NAMES, default="right", help="leg under study (default: right)")
    demo.add_argument("--cycles", type=int, default=10, help="number of step-up cycles (default: 10)")
    demo.add_argument("--filter", choices=choices.FILTER_NAMES, default=None,
                      help=f"orientation filter (default: {choices.DEFAULT_FILTER})")

    proc = sub.add_parser("process", help="process one recorded session folder into results.json")
    proc.add_argument("session", type=Path, metavar="SESSION_DIR", help="folder with the session's recordings")
    proc.add_argument("--out", type=Path, required=True, help="output folder")
    proc.add_argument("--filter", choices=choices.FILTER_NAMES, default=choices.DEFAULT_FILTER,
                      help=f"orientation filter (default: {choices.DEFAULT_FILTER})")
    proc.add_argument("--lang", choices=choices.LANGUAGE_NAMES, default=None,
                      help=f"language of the report and of the messages (default: report in "
                           f"{choices.DEFAULT_LANGUAGE}, messages in English)")
    proc.add_argument("--side", choices=choices.SIDE_NAMES, default=None,
                      help="leg under study (default: from the file names or session.json)")
    proc.add_argument("--angles", choices=choices.ANGLE_CONVENTION_NAMES, default=choices.DEFAULT_ANGLE_CONVENTION,
                      help=f"knee angle convention (default: {choices.DEFAULT_ANGLE_CONVENTION}, the clinical one)")
    proc.add_argument("--calibration", choices=choices.CALIBRATION_NAMES, default=choices.DEFAULT_CALIBRATION,
                      help="segment axes from standing + supine (static, default) or standing + the knee's "
                           "flexion axis on the task (functional: for a lying posture not held toes-up)")
    proc.add_argument("--heading", choices=choices.HEADING_NAMES, default=choices.DEFAULT_HEADING,
                      help="thigh-shank heading: the magnetometers, the knee's hinge constraint, or auto (default: "
                           "the magnetometers unless they disagree with the constraint, then the constraint)")
    proc.add_argument("--any-rate", action="store_true",
                      help="accept recordings whose rate is not the protocol's 100 Hz")
    proc.add_argument("--task", choices=choices.TASK_NAMES, default=choices.DEFAULT_TASK,
                      help=f"motor task recorded (default: {choices.DEFAULT_TASK})")
    proc.add_argument("--compare-with", type=Path, default=None, metavar="RESULTS_JSON",
                      help="an earlier analysis' results.json (or its output folder): the reports then compare the "
                           "two sessions side by side (e.g. before and after treatment)")
    proc.add_argument("--involved", choices=choices.SIDE_NAMES, default=None,
                      help="the involved knee of a two-knee session, the numerator of the limb symmetry index "
                           "(default: the patient's side in session.json)")
    proc.add_argument("--exclude-cycles", default="", metavar="N[,N...]",
                      help="cycles to leave out of the statistics, numbered as the report numbers them (e.g. 3,7; "
                           "right:3,left:7 in a session of both knees); the report names them as excluded by the "
                           "clinician, apart from the cycles the pipeline rejected")
    proc.add_argument("--exclude-reason", default="", metavar="TEXT",
                      help="why those cycles are excluded (recorded with them, with your user name and the time)")

    view = sub.add_parser("view", help="serve the live 3D femur-tibia animation of a processed session")
    view.add_argument("out", type=Path, metavar="OUT_DIR", help="a folder written by chakamo process or demo")
    view.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    view.add_argument("--port", type=int, default=8080, help="port (default: 8080)")
    view.add_argument("--lang", choices=choices.LANGUAGE_NAMES, default=None,
                      help="viewer language (default: the session's)")


def _single_threaded_blas() -> None:
    """One BLAS thread for this process unless the user set a number (read when numpy is first imported).

    The pipeline's linear algebra is small (the figure-eight fit's least squares: ~6000 × 9) and OpenBLAS's
    threads only cost there: each ``lstsq`` took 14 ms instead of 0.3 ms on this 2-core machine under load,
    0.45 s of a cold ``chakamo process``; the second core renders the reports instead.  The results are
    byte-identical (``python -m benchmarks.same_outputs``)."""
    import os

    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")


def _exclusions(args: argparse.Namespace) -> tuple:
    """``--exclude-cycles`` / ``--exclude-reason`` as :class:`app.pipeline.exclusions.CycleExclusion` s, recorded as
    excluded by the user running the command (ValueError naming the option when the list is malformed)."""
    import getpass

    from app.cli.admin import CliError
    from app.pipeline.exclusions import BadCycle, parse_cli

    if not args.exclude_cycles.strip():
        return ()
    try:
        by = getpass.getuser()
    except (KeyError, OSError):  # no name for this uid (a container)
        by = "command line"
    try:
        return parse_cli(args.exclude_cycles, reason=args.exclude_reason, by=by)
    except BadCycle as exc:
        raise CliError("cli.exclude_cycles", item=exc.item) from None


def run(args: argparse.Namespace) -> int:
    """Carry out a parsed ``demo`` / ``process`` / ``view`` command."""
    if args.command == "demo":
        from app.pipeline.demo import run_demo

        run_demo(args.out, seed=args.seed, side=args.side, n_cycles=args.cycles, filter_name=args.filter)
    elif args.command == "process":
        _single_threaded_blas()
        from app.pipeline import timings
        from app.pipeline.render import ForkedRenderers

        expected_fs_hz = None if args.any_rate else 100.0
        # forked before numpy is imported: the helper reads the session, then imports the report libraries,
        # while this process loads numba and the pipeline
        with ForkedRenderers(read=(args.session, expected_fs_hz)) as renderer:
            with timings.stage("imports"):
                from app.pipeline.process import process_folder
                from app.pipeline.session import ProcessOptions

            options = ProcessOptions(filter_name=args.filter, side=args.side, angle_method=args.angles,
                                     calibration=args.calibration, task=args.task, heading=args.heading,
                                     expected_fs_hz=expected_fs_hz, language=args.lang or choices.DEFAULT_LANGUAGE,
                                     involved=args.involved, exclusions=_exclusions(args))
            _, written = process_folder(args.session, args.out, options, progress=_progress(args.lang), renderer=renderer,
                                        compare_with=args.compare_with)
        for path in written:
            print(path)
    elif args.command == "view":
        from app.pipeline.view import serve_view

        serve_view(args.out, host=args.host, port=args.port, language=args.lang)
    return 0
