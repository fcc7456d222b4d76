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
``chakamo migrate`` / ``worker`` / ``reprocess --filter NAME --since DATE``
    The scaled-out deployment: schema upgrade, a Celery worker, a cohort queued again (``app/cli/ops.py``).

Errors a user can cause end with a one-line message on stderr and exit status 2; nothing is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from estimators import __version__
from estimators.orientation import DEFAULT_METHOD, METHODS


def _progress(stage: str, fraction: float) -> None:
    print(f"[{100 * fraction:3.0f} %] {stage}", file=sys.stderr, flush=True)


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="chakamo", description="Clinical 3D knee kinematics from two IMUs.")
    parser.add_argument("--version", action="version", version=f"chakamo {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    demo = sub.add_parser("demo", help="simulate a session with known truth, process it, print the accuracy")
    demo.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default: out/demo)")
    demo.add_argument("--seed", type=int, default=7, help="random seed of the simulated session (default: 7)")
    demo.add_argument("--side", choices=("right", "left"), default="right", help="leg under study (default: right)")
    demo.add_argument("--cycles", type=int, default=10, help="number of step-up cycles (default: 10)")
    demo.add_argument("--filter", choices=METHODS, default=None, help=f"orientation filter (default: {DEFAULT_METHOD})")

    proc = sub.add_parser("process", help="process one recorded session folder into results.json")
    proc.add_argument("session", type=Path, metavar="SESSION_DIR", help="folder with the session's recordings")
    proc.add_argument("--out", type=Path, required=True, help="output folder")
    proc.add_argument("--filter", choices=METHODS, default=DEFAULT_METHOD,
                      help=f"orientation filter (default: {DEFAULT_METHOD})")
    proc.add_argument("--lang", choices=("es", "en", "pt"), default="es", help="report language (default: es)")
    proc.add_argument("--side", choices=("right", "left"), default=None,
                      help="leg under study (default: from the file names or session.json)")
    proc.add_argument("--angles", choices=("grood_suntay", "thesis_zyx"), default="grood_suntay",
                      help="knee angle convention (default: grood_suntay, the clinical one)")
    proc.add_argument("--calibration", choices=("static", "functional"), default="static",
                      help="segment axes from standing + supine (static, default) or standing + the knee's "
                           "flexion axis on the task (functional: for a lying posture not held toes-up)")
    proc.add_argument("--any-rate", action="store_true",
                      help="accept recordings whose rate is not the protocol's 100 Hz")
    from estimators.motor_task import TASKS  # the task names, next to the only option that needs them

    proc.add_argument("--task", choices=tuple(TASKS), default="step_up",
                      help="motor task recorded (default: step_up)")

    view = sub.add_parser("view", help="serve the live 3D femur-tibia animation of a processed session")
    view.add_argument("out", type=Path, metavar="OUT_DIR", help="a folder written by chakamo process or demo")
    view.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    view.add_argument("--port", type=int, default=8080, help="port (default: 8080)")
    view.add_argument("--lang", choices=("es", "en", "pt"), default=None, help="viewer language (default: the session's)")

    walk = sub.add_parser("walk", help="foot-mounted pedestrian dead reckoning of one walk")
    walk.add_argument("file", type=Path, metavar="FILE", help="the walk recording")
    walk.add_argument("--format", choices=("iez", "npz"), default="iez", help="input format (default: iez)")
    walk.add_argument("--sensor", type=int, choices=(1, 2), default=1, help="which foot sensor (default: 1)")
    walk.add_argument("--method", default="chakamo", help="PDR method (default: chakamo)")
    walk.add_argument("--detector", choices=("c123", "pitch"), default="c123", help="stance detector (default: c123)")
    walk.add_argument("--json", type=Path, default=None, metavar="OUT", help="write the trajectory and metrics as JSON")
    walk.add_argument("--plot", type=Path, default=None, metavar="OUT.svg", help="write the 2D trajectory as SVG")
    walk.add_argument("--distance", type=float, default=22.1, metavar="M",
                      help="true path length for the distance error (default: 22.1 m, the thesis' circuit)")

    markov = sub.add_parser("markov", help="Markovian Kalman filters on a multi-segment research CSV")
    markov.add_argument("file", type=Path, metavar="FILE", help="CSV with per-segment IMU (and encoder) columns")
    markov.add_argument("--out", type=Path, required=True, help="output folder (angles.csv, markov.json)")
    markov.add_argument("--method", choices=("auto", "mjls", "kf", "sme", "smea"), default="auto",
                        help="filter (default: auto — sme with encoders, smea for thigh+shank without)")
    markov.add_argument("--zeta", type=float, default=None, metavar="G",
                        help="accelerometer trust threshold ζ, fraction of g (default: the method's)")
    markov.add_argument("--joint-axis", choices=("x", "y", "z"), default="x", help="sensor axis of the joints")
    markov.add_argument("--still", type=float, default=1.0, metavar="S",
                        help="seconds of still reference pose at the start (default: 1)")

    from app.cli import admin as admin_cli, ops as ops_cli

    admin_cli.add_parsers(sub)
    ops_cli.add_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    try:
        if args.command == "demo":
            from app.pipeline.demo import run_demo

            run_demo(args.out, seed=args.seed, side=args.side, n_cycles=args.cycles, filter_name=args.filter)
        elif args.command == "process":
            from app.pipeline.session import ProcessOptions
            from app.pipeline.process import process_folder

            options = ProcessOptions(filter_name=args.filter, side=args.side, angle_method=args.angles,
                                     calibration=args.calibration, task=args.task,
                                     expected_fs_hz=None if args.any_rate else 100.0, language=args.lang)
            _, written = process_folder(args.session, args.out, options, progress=_progress)
            for path in written:
                print(path)
        elif args.command == "view":
            from app.pipeline.view import serve_view

            serve_view(args.out, host=args.host, port=args.port, language=args.lang)
        elif args.command == "walk":
            from app.research.walk import run_walk

            run_walk(args.file, fmt=args.format, sensor=args.sensor, method=args.method, detector=args.detector,
                     json_out=args.json, plot_out=args.plot, true_distance_m=args.distance)
        elif args.command == "markov":
            from app.research.markov import run_markov

            run_markov(args.file, args.out, method=args.method, zeta_g=args.zeta, joint_axis=args.joint_axis,
                       still_s=args.still)
        elif args.command in ("serve", "clinics", "users", "tokens"):
            from app.cli.admin import run

            return run(args)
        elif args.command in ("migrate", "worker", "reprocess"):
            from app.cli.ops import run

            return run(args)
    except (ValueError, OSError) as exc:
        print(f"chakamo {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
