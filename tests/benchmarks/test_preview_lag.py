"""benchmarks/preview_lag.py's ``--before COMMIT``: the commit's whole recording page (record.js and the metawear
modules, which must agree with each other) is served; a commit git does not know is refused at once with the reason,
before any server or browser starts."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from benchmarks import preview_lag

ROOT = Path(__file__).resolve().parents[2]


def _known(commit: str) -> bool:
    return subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{commit}^{{commit}}"],
                          capture_output=True).returncode == 0


def test_an_unknown_commit_is_refused_before_anything_starts(monkeypatch):
    started = []
    monkeypatch.setattr(preview_lag, "served_app", lambda *a: started.append(a))
    with pytest.raises(SystemExit) as exc:
        preview_lag.main(["--before", "no-such-commit"])
    assert "no-such-commit" in str(exc.value.code) and not started


@pytest.mark.skipif(not _known("34ed36f"), reason="no git history with 34ed36f here")
def test_the_commits_page_is_served_whole():
    # 34ed36f: the flexion-only preview, its record.js calling the recorder's flexion() (gone since)
    page = preview_lag.old_page_js("34ed36f")
    assert b"recorder.flexion()" in page["static/views/record.js"]
    assert b"flexion()" in page["static/metawear/recorder.js"]
    assert set(page) == set(preview_lag.PAGE_JS) | set(preview_lag.I18N)  # and the tables, with its old keys
    assert "record.preview" in json.loads(page["static/i18n/pt.json"])  # the old page's text, deleted since
