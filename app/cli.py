"""The ``chakamo`` command line.

Subcommands
-----------
``chakamo demo --out DIR``
    Simulate a realistic sensor with known truth, calibrate its magnetometer, run every orientation
    filter and print their accuracy (until the knee pipeline lands; then it runs a whole session).

Errors a user can cause end with a one-line message on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from estimators import __version__


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="chakamo", description="Clinical 3D knee kinematics from two IMUs.")
    parser.add_argument("--version", action="version", version=f"chakamo {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    demo = sub.add_parser("demo", help="simulate a sensor with known truth and compare the orientation filters")
    demo.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default: out/demo)")
    demo.add_argument("--seed", type=int, default=7, help="random seed of the simulated sensor (default: 7)")
    demo.add_argument("--duration", type=float, default=60.0, metavar="S",
                      help="length of the simulated motion, s (default: 60)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    try:
        if args.command == "demo":
            from app.demo import run_demo

            run_demo(args.out, seed=args.seed, duration_s=args.duration)
    except (ValueError, OSError) as exc:
        print(f"chakamo {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
