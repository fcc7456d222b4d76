"""The load benchmark (benchmarks/load.py) run small on the embedded engine: its own server, 2 clinicians.

Nothing is timed: the test checks that the benchmark's clinicians really went through every step, that its
verification found each upload stored and each job done, and that the read load was answered — i.e. that
the check the benchmark's exit status stands for can pass, and counts what it claims to count.
"""

from __future__ import annotations

import pytest

from benchmarks import load
from benchmarks.live_services import Missing


def test_two_clinicians_on_the_inprocess_backend_lose_nothing(capsys):
    try:
        summary = load.main(["--backend", "inprocess", "--clinicians", "2", "--workers", "2", "--read-seconds", "2",
                             "--timeout-s", "240"])
    except Missing as exc:
        pytest.skip(str(exc))

    assert summary.errors == 0, [str(c.error) for c in summary.clinicians]
    assert summary.lost == [] and summary.jobs == {"done": 2, "failed": 0, "lost": 0}
    assert summary.exit_status == 0
    for c in summary.clinicians:
        assert c.files_uploaded == 24 and c.job_id is not None  # the demo session's 24 MetaBase files
        assert len(c.sha256) == 24
        assert set(c.phase_s) == {"create", "upload", "process request", "job wait", "download"}
        assert c.poll_s and c.finished_at is not None
    # each clinician uploaded a session of their own: no file's content was stored already by another
    first, second = summary.clinicians
    assert not first.sha256 & second.sha256
    # 50 requests/s for 2 s, twice, over 9 endpoints, every one answered 200
    assert len(summary.read_during) == len(summary.read_after) == 100 and summary.read_errors == 0
    assert {r.path for r in summary.read_after} == set(summary.read_paths)
    out = capsys.readouterr().out
    assert "| jobs | done | failed | lost |" in out and "| 2 | 2 | 0 | 0 | 0 |" in out


def test_same_files_gives_every_clinician_the_reference_session(tmp_path):
    made = load.sessions(tmp_path, 2, same_files=True)
    assert len(made) == 3 and made[0] == made[1] == made[2] and len(made[0]) == 24
