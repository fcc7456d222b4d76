"""Research commands: ``chakamo walk`` and ``chakamo markov``.

``chakamo walk FILE [--format iez|npz] [--sensor 1|2] [--method NAME] [--json OUT] [--plot OUT.svg]``
    Foot-mounted pedestrian dead reckoning: trajectory, strides and metrics (:mod:`app.research.walk`).
``chakamo markov FILE --out DIR [--method auto|mjls|kf|sme|smea] [--zeta G] [--joint-axis x|y|z] [--still S]``
    Markovian Kalman filters on a research CSV of several segment IMUs (format in :mod:`app.research.markov`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.choices import MARKOV_METHODS

COMMANDS = ("walk", "markov")


def add_parsers(sub) -> None:
    """Register ``walk`` and ``markov`` on the ``chakamo`` subparsers."""
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
    markov.add_argument("--method", choices=MARKOV_METHODS, default="auto",
                        help="filter (default: auto — sme with encoders, smea for thigh+shank without)")
    markov.add_argument("--zeta", type=float, default=None, metavar="G",
                        help="accelerometer trust threshold ζ, fraction of g (default: the method's)")
    markov.add_argument("--joint-axis", choices=("x", "y", "z"), default="x", help="sensor axis of the joints")
    markov.add_argument("--still", type=float, default=1.0, metavar="S",
                        help="seconds of still reference pose at the start (default: 1)")


def run(args: argparse.Namespace) -> int:
    """Carry out a parsed ``walk`` / ``markov`` command."""
    if args.command == "walk":
        from app.research.walk import run_walk

        run_walk(args.file, fmt=args.format, sensor=args.sensor, method=args.method, detector=args.detector,
                 json_out=args.json, plot_out=args.plot, true_distance_m=args.distance)
    elif args.command == "markov":
        from app.research.markov import run_markov

        run_markov(args.file, args.out, method=args.method, zeta_g=args.zeta, joint_axis=args.joint_axis,
                   still_s=args.still)
    return 0
