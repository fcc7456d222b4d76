"""benchmarks/preview_lag.py's ``--before COMMIT``: a commit whose record.js cannot drive today's recorder (older
than 913bbb8, which made the page pass GET /options' live_checks to the Recorder) is refused at once with the
reason, before any server or browser starts (it used to wait forever for the sensors' identification)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from benchmarks import preview_lag

ROOT = Path(__file__).resolve().parents[2]


def _known(commit: str) -> bool:
    return subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{commit}^{{commit}}"],
                          capture_output=True).returncode == 0


@pytest.mark.skipif(not _known("913bbb8"), reason="no git history with 913bbb8 here")
def test_a_commit_before_the_served_thresholds_is_refused(monkeypatch):
    started = []
    monkeypatch.setattr(preview_lag, "served_app", lambda *a: started.append(a))
    with pytest.raises(SystemExit) as exc:
        preview_lag.main(["--before", "913bbb8^", "--seconds", "1"])
    assert "predates 913bbb8" in str(exc.value.code) and not started
    with pytest.raises(SystemExit) as exc:
        preview_lag.main(["--before", "no-such-commit"])
    assert "no-such-commit" in str(exc.value.code) and not started
    assert b"live_checks" in preview_lag.old_record_js("913bbb8")
