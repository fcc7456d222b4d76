"""benchmarks/robustness.py runs end to end on one drawn session: the benchmark imports the pipeline by its
current module paths and prints its table (a smoke test: the accuracy goals are the benchmark's, never a test's)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_the_robustness_benchmark_runs_one_session():
    run = subprocess.run([sys.executable, "-m", "benchmarks.robustness", "--n", "1", "--seed0", "3", "--worst", "1"],
                         cwd=REPO, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "seed    3" in run.stdout and "1 sessions" in run.stdout and "worst 1" in run.stdout, run.stdout
