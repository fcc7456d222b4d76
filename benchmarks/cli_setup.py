"""The set-up commands' start-to-end time as fresh processes (issue 17, §5: goal ≤ 1 s each).

``python -m benchmarks.cli_setup [--repeats 5]`` makes a temporary data directory (production settings, no
``CHAKAMO_SECRET_KEY``: the set-up commands must not need one), then runs ``chakamo clinics create``,
``chakamo users create`` and ``chakamo tokens create`` ``--repeats`` times each as new processes and prints the
median and worst wall time and the median CPU time (user + system of the child) per command, with the load
average beside them: on a shared machine the wall time is mostly waiting for a core, the CPU time is not.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time


def _run(args: list[str], env: dict, stdin: str | None = None) -> tuple[float, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "app.cli.main", *args], env=env, input=stdin, capture_output=True,
                         text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise SystemExit(f"chakamo {' '.join(args)} failed: {out.stderr.strip()}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    opts = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        env = {k: v for k, v in os.environ.items() if not k.startswith("CHAKAMO_")} | {
            "CHAKAMO_DATA_DIR": tmp, "CHAKAMO_ENV": "production"}
        _run(["clinics", "create", "Warm-up"], env)  # the first call creates and migrates the database
        rows = []
        for name, make in (
                ("clinics create", lambda i: (["clinics", "create", f"Clinic {i}"], None)),
                ("users create", lambda i: (["users", "create", "--clinic", "Warm-up", "--email", f"u{i}@x.org",
                                             "--role", "clinician", "--password-stdin"],
                                            "correct horse battery staple\n")),
                ("tokens create", lambda i: (["tokens", "create", "--clinic", "Warm-up"], None))):
            walls, cpus = [], []
            for i in range(opts.repeats):
                args, stdin = make(i)
                wall, cpu = _run(args, env, stdin)
                walls.append(wall)
                cpus.append(cpu)
            rows.append((name, statistics.median(walls), max(walls), statistics.median(cpus), os.getloadavg()[0]))
    print("| command | wall median | wall max | CPU median | load (1 min) |")
    print("| --- | --- | --- | --- | --- |")
    for name, med, worst, cpu, load in rows:
        print(f"| `chakamo {name}` | {med:.2f} s | {worst:.2f} s | {cpu:.2f} s | {load:.1f} |")


if __name__ == "__main__":
    main()
