"""benchmarks/compile_work.py counts numba's compilation of the chakamo kernels per function, in a fresh process
(numba's cache folder is chosen before numba is imported): every project function of the first call is compiled
once, and the total is the sum of every function's own count."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_compilation_is_counted_per_function():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("NUMBA_CACHE_DIR", None)
    out = subprocess.run([sys.executable, "-m", "benchmarks.compile_work", "--top", "100"], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=600, check=True).stdout
    rows = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.split("|")]
        if len(cells) == 3 and cells[1].isdigit():
            rows[cells[0]] = (int(cells[1]), int(cells[2]))
    total = rows.pop("total (every function)")
    kernels = "estimators.orientation.chakamo_kernels."
    for name in ("chakamo_step", "chakamo_batch", "_bias_update", "smooth_bias_batch", "robust_heading_batch"):
        assert rows[kernels + name][1] > 0, name
    # every project function compiles once: one signature each, no helper compiled again per literal argument (as
    # when the state indices were Python ints: _qnorm three times, _biquad9 twice)
    ours = {name: compiles for name, (compiles, _) in rows.items() if name.startswith("estimators.")}
    assert ours and all(compiles == 1 for compiles in ours.values()), ours
    assert total[0] == sum(c for c, _ in rows.values())
    assert abs(total[1] - sum(k for _, k in rows.values())) <= len(rows)  # each row rounded down to thousands
