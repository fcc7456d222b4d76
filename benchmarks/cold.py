r"""Cold start: the ``chakamo`` command line as a fresh process, as a clinician's shell or a job runner starts it.

Usage
-----
``python -m benchmarks.cold [--session DIR] [--task NAME] [--repeats 5] [--commands help,version,process,floor] [--json OUT] [--imports N]``

Each command runs as a new subprocess of this interpreter, ``[sys.executable, "-c", "<entry>", ...]`` with
``<entry>`` calling ``app.cli.console`` as the console script ``chakamo`` does, so it measures the
checkout the interpreter imports ``app`` from (run from the worktree or set ``PYTHONPATH``).  One warm-up run of
each command fills numba's on-disk cache and the ``.pyc`` files first (with ``PYTHONDONTWRITEBYTECODE`` removed
from its environment: set in a shell, it would have every timed run compile the project's modules again, ~0.13 s
of CPU in the parent alone, which no installed copy pays: ``pip install`` and the Docker image compile them);
then ``--repeats`` runs give the median (and the spread, min–max) of

* *wall* — from ``Popen`` to the child's exit, s;
* *CPU* — the child's user + system time from the same rusage, s: on a shared, loaded machine wall time
  swings with the other processes, CPU time much less, so read it beside wall;
* *peak RSS* — the child's ``ru_maxrss`` from ``os.wait4`` (its own rusage, not the sum of all children), MB;
* the split of a ``process`` run, from two sources:

  - **progress marks**, always: ``chakamo process`` prints ``[ nn %] stage`` lines on stderr (flushed); this
    script stamps each line on arrival.  The entry code adds one mark, ``chakamo-timing: cli-imported``, when
    ``app.cli`` has been imported.  Spans: *start → cli-imported* (interpreter start and the CLI's top-level
    imports), *cli-imported → read* (argument parsing and the imports of the process command), *read → reports*
    (reading, the session pipeline, its deferred imports), *reports → write* (rendering every report, with the
    report modules' imports), *write → done* (writing the files), *done → exit* (teardown);
  - **the child's own stage times**, when the CLI prints them.  ``CHAKAMO_TIMINGS=1`` (set by this script)
    asks ``chakamo`` to write one stderr line per finished stage, ::

        chakamo-timing: <stage> <seconds> [<cpu_seconds>]

    ``<stage>`` a word without spaces, ``<seconds>`` a float (``time.perf_counter`` differences), optionally
    followed by the stage's CPU time (``time.process_time`` differences; on a loaded machine the CPU column
    is the one to compare between runs).  The stages this
    table expects: ``imports`` (every module import the command paid: top-level ones and those deferred into
    functions, summed), ``read``, ``pipeline``, ``reports`` (all renderers), ``write``, ``total`` (from the first
    line of ``app.cli`` to the end of ``main``); optional finer ones are printed too (e.g. ``report.pdf``,
    ``report.html``, ``scene.viser``, ``angles.xlsx``).  A stage printed several times is summed.  Lines of the
    form ``chakamo-timing: <mark>`` (no number) are marks as above.

``chakamo process`` runs in three processes (:class:`app.pipeline.render.ForkedRenderers`): forked before numpy
is imported, a helper reads the session (its ``read`` stage) and imports the report libraries
(``render.imports``) while the parent imports the pipeline (``imports``) and loads numba's kernels
(``kernels``: numba's set-up and the chosen filter's cached kernels), then waits for the session
(``read.wait``) and computes (``pipeline``); the helper and a second one forked from it render the reports side
by side (``report.pdf`` ...; the parent's ``reports`` stage is mostly waiting for them), and the parent writes.
Each process prints ``chakamo-process: <name> <peak RSS MB> <CPU s>`` (the renderers: their rendering CPU), so
the table shows every process's peak (the parent's rusage gives only the largest) and their sum, and a
*critical path from CPU times*: what the wall time would be on two otherwise idle cores (:func:`critical_path_cpu`),
the number to read on a machine shared with other work, beside the wall time.

``--imports N`` adds one more ``process`` run under ``python -X importtime`` and prints the N heaviest imports
of third-party packages *by the project module that imports them* (``app.*``, ``estimators.*``, ``reports.*``;
cumulative ms, as ``-X importtime`` measures them, inflated a little by the measurement itself): the list
of what to import later or not at all.  A package counts once, under the first project module whose import
loaded it.

``floor`` is not a command but the part of every ``chakamo process`` no change of ours can remove: a fresh
interpreter importing numpy and numba and loading one cached kernel of the default filter (numba's set-up:
its typing and lowering registries, LLVM, and the ``scipy.linalg`` import numba makes to find BLAS).  Measured
in the same run as ``process``, it tells how loaded the machine was and how far above the floor the command is.

The goals of issue 12 §6 are printed beside the numbers: ``chakamo --help`` ≤ 0.3 s, ``chakamo process`` on the
demo's 10-cycle session with every output ≤ 1.5 s wall and ≤ 300 MB peak RSS.

The session is ``--session`` or, by default, ``$TMPDIR/chakamo_cold/session``, created with ``chakamo demo`` (the
demo's default 10 cycles, seed 7) when missing.  Timings on a shared machine are noisy: read the medians.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ENTRY = ("import sys, time\n"
         "from app.cli import console\n"
         "print('chakamo-timing: cli-imported', file=sys.stderr, flush=True)\n"
         "console()\n")
#: the floor of any ``chakamo process``: the interpreter, numpy, numba, and numba's set-up on loading one cached
#: kernel (of the default filter: the process command's own first load), nothing of the session
FLOOR_ENTRY = ("import numpy as np\n"
               "from estimators.orientation import chakamo_kernels as k\n"
               "k.rotate_batch(np.ones((10, 4)), np.zeros((10, 3)))\n")
TIMING_ENV = "CHAKAMO_TIMINGS"
_TIMING_LINE = re.compile(r"^chakamo-timing:\s+(\S+)(?:\s+([-+0-9.eE]+)(?:\s+([-+0-9.eE]+))?)?\s*$")
_PROCESS_LINE = re.compile(r"^chakamo-process:\s+(\S+)\s+([-+0-9.eE]+)\s+([-+0-9.eE]+)(?:\s+([-+0-9.eE]+))?\s*$")
_PROGRESS_LINE = re.compile(r"^\[\s*\d+\s*%\]\s+(\S.*?)\s*$")
GOALS = {"help": (0.3, None), "version": (None, None), "process": (1.5, 300.0), "floor": (None, None)}
MARK_SPANS = [("start", "cli-imported", "interpreter + app.cli imports"),
              ("cli-imported", "read", "parse + process-command imports"),
              ("read", "reports", "read + pipeline (+ deferred imports)"),
              ("reports", "write", "reports (+ their imports)"),
              ("write", "done", "write"),
              ("done", "exit", "teardown")]
CHILD_STAGES = ["imports", "read", "pipeline", "reports", "write", "total"]


@dataclass
class Run:
    wall_s: float
    cpu_s: float
    peak_rss_mb: float
    returncode: int
    marks_s: dict[str, float] = field(default_factory=dict)  # first arrival of each mark, s after Popen
    stages_s: dict[str, float] = field(default_factory=dict)  # the child's own stage times, summed per stage
    stages_cpu_s: dict[str, float] = field(default_factory=dict)  # their CPU times, when the child prints them
    processes: dict[str, tuple[float, float, float]] = field(default_factory=dict)  # name -> (peak RSS MB, CPU s, PSS MB)
    stderr_tail: str = ""


def run_cli(args: list[str], env: dict[str, str] | None = None, entry: str = ENTRY, *,
            write_bytecode: bool = False) -> Run:
    """One fresh ``chakamo`` process; wall, peak RSS (``os.wait4``) and the stamped stderr lines.
    ``write_bytecode``: let it write ``.pyc`` files even when ``PYTHONDONTWRITEBYTECODE`` is set (the warm-up)."""
    env = dict(os.environ if env is None else env)
    env[TIMING_ENV] = "1"
    if write_bytecode:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
    if entry is FLOOR_ENTRY:
        env.setdefault("OPENBLAS_NUM_THREADS", "1")  # as chakamo process sets it
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", entry, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, env=env)
    marks: dict[str, float] = {"start": 0.0}
    stages: dict[str, float] = {}
    stages_cpu: dict[str, float] = {}
    processes: dict[str, tuple[float, float, float]] = {}
    tail: list[str] = []

    def read_stderr() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            now = time.perf_counter() - start
            line = line.rstrip("\n")
            tail.append(line)
            del tail[:-20]
            p = _PROCESS_LINE.match(line)
            if p:
                processes[p.group(1)] = (float(p.group(2)), float(p.group(3)),
                                         float(p.group(4)) if p.group(4) else float("nan"))
                continue
            m = _TIMING_LINE.match(line)
            if m and m.group(2) is not None:
                stages[m.group(1)] = stages.get(m.group(1), 0.0) + float(m.group(2))
                if m.group(3) is not None:
                    stages_cpu[m.group(1)] = stages_cpu.get(m.group(1), 0.0) + float(m.group(3))
                continue
            name = m.group(1) if m else (g.group(1) if (g := _PROGRESS_LINE.match(line)) else None)
            if name is not None:
                marks.setdefault(name, now)

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait again
    reader.join(timeout=10.0)
    marks["exit"] = wall
    rss_mb = usage.ru_maxrss / 1024.0  # Linux: kilobytes
    cpu_s = usage.ru_utime + usage.ru_stime
    return Run(wall, cpu_s, rss_mb, proc.returncode, marks, stages, stages_cpu, processes, "\n".join(tail))


def ensure_session(session: Path | None) -> Path:
    """The given session folder, or the demo's one under the temp folder (made with ``chakamo demo`` if missing)."""
    if session is not None:
        if not session.is_dir():
            raise SystemExit(f"--session {session} is not a folder: give a session folder or leave it out")
        return session
    root = Path(tempfile.gettempdir()) / "chakamo_cold"
    session = root / "session"
    if not (session / "session.json").exists():
        print(f"creating the demo session in {root} (chakamo demo, once) ...", file=sys.stderr)
        done = subprocess.run([sys.executable, "-c", ENTRY, "demo", "--out", str(root)], capture_output=True,
                              text=True)
        if done.returncode != 0 or not session.is_dir():
            raise SystemExit(f"chakamo demo failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return session


PROJECT_PACKAGES = ("app", "estimators", "reports")
_IMPORTTIME_LINE = re.compile(r"^import time:\s+(\d+)\s+\|\s+(\d+)\s+\|( *)(\S+)\s*$")


def heavy_imports(importtime_stderr: str, top: int) -> list[tuple[str, str, float]]:
    """``(project module, third-party package, cumulative ms)`` from ``-X importtime`` output, heaviest first.

    The output lists each module after the modules its import loaded (post-order), indented two spaces per
    level; a third-party module is attributed to its nearest project-module ancestor, and only the outermost
    third-party module of a chain counts (its cumulative time holds the rest).  Imports made inside a function
    call appear at the top level of the output: they are listed as deferred.  The standard library is left out.
    """
    entries = []  # (depth, name, cumulative_us)
    for line in importtime_stderr.splitlines():
        m = _IMPORTTIME_LINE.match(line)
        if m:
            entries.append((len(m.group(3)) // 2, m.group(4), int(m.group(2))))
    parent: list[int | None] = [None] * len(entries)
    waiting: dict[int, list[int]] = {}  # depth -> indices of modules waiting for their parent (depth - 1)
    for i, (depth, _, _) in enumerate(entries):
        for child in waiting.pop(depth + 1, []):
            parent[child] = i
        waiting.setdefault(depth, []).append(i)

    def is_project(name: str) -> bool:
        return name.split(".")[0] in PROJECT_PACKAGES

    cli_done = next((i for i, e in enumerate(entries) if e[0] == 0 and e[1].split(".")[0] == "app"), len(entries))
    rows = []
    for i, (_, name, cum_us) in enumerate(entries):
        top_name = name.split(".")[0]
        if is_project(name) or top_name in sys.stdlib_module_names or top_name.startswith("_"):
            continue
        p = parent[i]
        if p is not None and not is_project(entries[p][1]):
            continue  # inside another third-party import: counted there
        if p is not None:
            owner = entries[p][1]
        else:
            owner = "(deferred: imported inside a call)" if i > cli_done else "(interpreter start-up)"
        rows.append((owner, name, cum_us / 1000.0))
    merged: dict[tuple[str, str], float] = {}
    for owner, name, ms in rows:
        key = (owner, name.split(".")[0])
        merged[key] = merged.get(key, 0.0) + ms
    out = sorted(((o, n, ms) for (o, n), ms in merged.items()), key=lambda r: -r[2])
    return out[:top]


def importtime_of(args: list[str]) -> str:
    env = dict(os.environ)
    env.pop(TIMING_ENV, None)
    done = subprocess.run([sys.executable, "-X", "importtime", "-c", ENTRY, *args], capture_output=True, text=True,
                          env=env)
    if done.returncode != 0:
        raise SystemExit(f"`chakamo {' '.join(args)}` under -X importtime failed ({done.returncode}):\n"
                         f"{done.stderr[-2000:]}")
    return done.stderr


def critical_path_cpu(run: Run) -> float | None:
    """What the run's wall time would be on two otherwise idle cores, from CPU times, s (None without the lines).

    ``chakamo process`` runs in three processes (``app.pipeline.render.ForkedRenderers``): the parent reads and
    computes while a helper imports the report libraries; then two helpers render while the parent waits; then
    the parent writes.  On a shared machine wall time measures the other processes too, CPU time does not, so
    the critical path is estimated as ``max(parent CPU before the reports, helper's read + imports CPU) +
    max(render CPU of a helper) + the parent's CPU in the reports stage (pickling) and in the write``, each a
    CPU time (what it takes alone on one core; page faults and the pipes' copies are in them, the scheduler's
    switches are not)."""
    procs, cpu = run.processes, run.stages_cpu_s
    if "main" not in procs:
        return None
    main_cpu = procs["main"][1]
    write = cpu.get("write", 0.0)
    helpers = [v[1] for k, v in procs.items() if k != "main"]
    if not helpers:
        return main_cpu
    reports = cpu.get("reports", 0.0)  # the parent's part: the report input, pickling it and the answers
    helper = cpu.get("render.imports", 0.0) + (cpu.get("read", 0.0) if "read.wait" in cpu else 0.0)
    return max(main_cpu - write - reports, helper) + reports + max(helpers) + write


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def _spread(values: list[float]) -> str:
    return f"{min(values):.2f}–{max(values):.2f}" if values else ""


def summarise(name: str, runs: list[Run]) -> dict[str, Any]:
    out: dict[str, Any] = {
        "command": name,
        "wall_s": _median([r.wall_s for r in runs]),
        "wall_range_s": [min(r.wall_s for r in runs), max(r.wall_s for r in runs)],
        "cpu_s": _median([r.cpu_s for r in runs]),
        "peak_rss_mb": _median([r.peak_rss_mb for r in runs]),
        "failed": sum(r.returncode != 0 for r in runs),
        "marks": {},
        "stages": {},
        "stages_cpu": {},
    }
    for a, b, label in MARK_SPANS:
        spans = [r.marks_s[b] - r.marks_s[a] for r in runs if a in r.marks_s and b in r.marks_s]
        if spans:
            out["marks"][label] = _median(spans)
    names = sorted({s for r in runs for s in r.stages_s}, key=lambda s: (s not in CHILD_STAGES,
                                                                           CHILD_STAGES.index(s) if s in CHILD_STAGES
                                                                           else 0, s))
    procs = sorted({p for r in runs for p in r.processes}, key=lambda p: (p != "main", p))
    out["processes"] = {p: {"peak_rss_mb": _median([r.processes[p][0] for r in runs if p in r.processes]),
                            "cpu_s": _median([r.processes[p][1] for r in runs if p in r.processes]),
                            "pss_mb": _median([r.processes[p][2] for r in runs if p in r.processes])} for p in procs}
    if procs:
        out["peak_rss_sum_mb"] = _median([sum(v[0] for v in r.processes.values()) for r in runs if r.processes])
        out["pss_sum_mb"] = _median([sum(v[2] for v in r.processes.values()) for r in runs if r.processes])
        paths = [critical_path_cpu(r) for r in runs]
        if all(x is not None for x in paths):
            out["critical_path_cpu_s"] = _median(paths)
    for s in names:
        out["stages"][s] = _median([r.stages_s[s] for r in runs if s in r.stages_s])
        cpu = [r.stages_cpu_s[s] for r in runs if s in r.stages_cpu_s]
        if cpu:
            out["stages_cpu"][s] = _median(cpu)
    return out


def format_tables(summaries: list[dict[str, Any]], repeats: int, load: tuple[list[float], list[float]] | None = None,
                  ) -> str:
    lines = [f"cold start: fresh `chakamo` processes, median of {repeats} after one warm-up run (numba cache warm)"]
    if load is not None:
        lines.append("load average (1, 5, 15 min) before " + ", ".join(f"{x:.2f}" for x in load[0])
                     + "; after " + ", ".join(f"{x:.2f}" for x in load[1]))
    lines += ["", f"{'command':<10} {'wall s':>7} {'range s':>11} {'CPU s':>6} {'peak RSS MB':>12} {'goal':>20}  verdict"]
    for s in summaries:
        wall_goal, rss_goal = GOALS.get(s["command"], (None, None))
        goal = " ".join(g for g in ((f"≤{wall_goal:g} s" if wall_goal else ""),
                                    (f"≤{rss_goal:g} MB" if rss_goal else "")) if g) or "-"
        ok = (wall_goal is None or s["wall_s"] <= wall_goal) and (rss_goal is None or s["peak_rss_mb"] <= rss_goal)
        verdict = ("FAILED RUNS " if s["failed"] else "") + ("met" if ok else "not met") if goal != "-" else ""
        lines.append(f"{s['command']:<10} {s['wall_s']:7.2f} {_spread(s['wall_range_s']):>11} {s['cpu_s']:6.2f} "
                     f"{s['peak_rss_mb']:12.0f} {goal:>20}  {verdict}")
    by_name = {s["command"]: s for s in summaries}
    if "floor" in by_name and "critical_path_cpu_s" in by_name.get("process", {}):
        floor, crit = by_name["floor"]["cpu_s"], by_name["process"]["critical_path_cpu_s"]
        lines += ["", f"process above the floor (CPU, same run): critical path {crit:.2f} s = floor {floor:.2f} s "
                      f"+ {crit - floor:.2f} s; on a quiet machine the floor is what `floor` measures there"]
    for s in summaries:
        if s.get("processes"):
            lines += ["", f"{s['command']}: per process (chakamo-process lines; median; PSS at the process's end)",
                      f"  {'process':<12} {'CPU s':>7} {'peak RSS MB':>12} {'PSS MB':>8}"]
            lines += [f"  {p:<12} {v['cpu_s']:7.2f} {v['peak_rss_mb']:12.0f} {v['pss_mb']:8.0f}"
                      for p, v in s["processes"].items()]
            lines.append(f"  {'sum':<12} {'':>7} {s['peak_rss_sum_mb']:12.0f} {s['pss_sum_mb']:8.0f}   "
                         "(RSS: shared pages counted in each process; PSS: shared among them)")
            if "critical_path_cpu_s" in s:
                lines.append(f"  critical path from CPU times (two idle cores): {s['critical_path_cpu_s']:.2f} s "
                             f"(goal ≤{GOALS['process'][0]:g} s)")
        if s["marks"]:
            lines += ["", f"{s['command']}: split from the progress marks (s, median)"]
            lines += [f"  {label:<40} {v:6.2f}" for label, v in s["marks"].items()]
        if s["stages"]:
            lines += ["", f"{s['command']}: the child's own stage times ({TIMING_ENV}=1; s, median)"]
            cpu = s.get("stages_cpu", {})
            lines += [f"  {name:<40} {v:6.2f}" + (f"   CPU {cpu[name]:6.2f}" if name in cpu else "")
                      for name, v in s["stages"].items()]
        elif s["command"] == "process":
            lines += ["", f"process: the CLI printed no `chakamo-timing: <stage> <s>` lines ({TIMING_ENV} hook absent)"]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--session", type=Path, default=None, help="session folder (default: the demo's, made once)")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per command (default: 5)")
    parser.add_argument("--commands", default="help,version,process,floor",
                        help="comma-separated subset of help,version,process,floor (default: all; floor: python, "
                             "numpy, numba and its first cached kernel, what every process command pays)")
    parser.add_argument("--json", type=Path, default=None, help="also write the summaries as JSON")
    parser.add_argument("--task", default=None, help="the process command's --task (e.g. gait for a walking session, "
                                                      "python -m benchmarks.knees --write DIR makes a four-sensor one)")
    parser.add_argument("--imports", type=int, default=0, metavar="N",
                        help="also list the N heaviest third-party imports of a process run, by importing module")
    args = parser.parse_args(argv)
    commands = [c.strip() for c in args.commands.split(",") if c.strip()]
    unknown = set(commands) - set(GOALS)
    if unknown:
        parser.error(f"unknown command(s) {sorted(unknown)}: choose from help, version, process, floor")
    session = ensure_session(args.session) if "process" in commands else None
    summaries = []
    load_before = list(os.getloadavg())
    with tempfile.TemporaryDirectory(prefix="chakamo_cold_out_") as tmp:
        argv_of = {"help": ["--help"], "version": ["--version"],
                   "process": ["process", str(session), "--out", str(Path(tmp) / "out"),
                               *(["--task", args.task] if args.task else [])], "floor": []}
        for name in commands:
            entry = FLOOR_ENTRY if name == "floor" else ENTRY
            warm = run_cli(argv_of[name], entry=entry, write_bytecode=True)  # fills numba's cache and the .pyc files
            if warm.returncode != 0:
                raise SystemExit(f"`chakamo {' '.join(argv_of[name])}` failed ({warm.returncode}):\n{warm.stderr_tail}")
            runs = [run_cli(argv_of[name], entry=entry) for _ in range(args.repeats)]
            summaries.append(summarise(name, runs))
        heavy = heavy_imports(importtime_of(argv_of["process"]), args.imports) if args.imports and session else []
    print(format_tables(summaries, args.repeats, (load_before, list(os.getloadavg()))))
    if heavy:
        print(f"\nprocess: the {len(heavy)} heaviest third-party imports, by the project module importing them "
              "(-X importtime, cumulative ms, one run)")
        print(f"  {'project module':<44} {'package':<22} {'ms':>7}")
        for owner, package, ms in heavy:
            print(f"  {owner:<44} {package:<22} {ms:7.0f}")
    if args.json:
        args.json.write_text(json.dumps(summaries, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
