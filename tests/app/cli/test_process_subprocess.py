"""``chakamo process`` as a fresh process (its forked reader and renderers, one BLAS thread) writes the same
bytes as :func:`app.pipeline.process.process_folder` run in this process without helpers."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from app.pipeline.demo import simulate_session, write_session
from app.pipeline.process import process_folder

ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the helpers need os.fork")
def test_a_fresh_process_writes_what_this_process_writes(tmp_path):
    write_session(tmp_path / "session", simulate_session(seed=6, side="left", n_cycles=3))
    _, expected = process_folder(tmp_path / "session", tmp_path / "here")
    env = dict(os.environ, PYTHONPATH=str(ROOT), CHAKAMO_TIMINGS="1")
    done = subprocess.run([sys.executable, "-c", "from app.cli import console; console()", "process",
                           str(tmp_path / "session"), "--out", str(tmp_path / "cli")],
                          capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == [str(tmp_path / "cli" / p.name) for p in expected]
    for path in expected:
        assert (tmp_path / "cli" / path.name).read_bytes() == path.read_bytes(), path.name
    # the helpers did the reading and the rendering (their own stage lines), not a fallback in the parent
    assert "chakamo-process: render1" in done.stderr and "chakamo-process: render2" in done.stderr
    assert "chakamo-timing: read.wait" in done.stderr
