"""The embedded engine's job helper process (:class:`app.jobs.compute.JobProcess`) when things go wrong around
it: it dies while idle or under a job, the job thread's progress relay raises, the server stops under a job.
The helper is real (spawned, warmed); its work is a stand-in that sends progress through the real pipe
(:func:`app.jobs.compute._send_progress`) so that these cases do not need a full computation."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest
from helper_processes import ended


def _steps(folder, options, lang, session_id, paired_id):
    """A job of ten progress steps (run in the helper)."""
    import app.jobs.compute as compute

    for i in range(10):
        compute._send_progress(f"s{session_id}-{i}", i / 10)
        time.sleep(0.1)
    return {"session": session_id}, {}


def _sleeps(folder, options, lang, session_id, paired_id):
    """A job that says it started, then takes ten minutes (run in the helper)."""
    import app.jobs.compute as compute

    compute._send_progress("started", 0.0)
    time.sleep(600)
    return {}, {}


@pytest.fixture
def compute():
    import app.jobs.compute as compute

    return compute


@pytest.fixture
def helper(compute):
    jp = compute.JobProcess()
    assert jp.wait_warm()
    yield jp
    jp.shutdown()


def _run(jp, monkeypatch, work, session_id, progress=lambda st, f: None):
    import app.jobs.compute as compute

    monkeypatch.setattr(compute, "_compute_here", work)
    return jp.run(progress, None, None, "en", session_id, None)


def _kill(jp):
    """SIGKILL the helper (as the out-of-memory killer would) and wait until it has exited."""
    pid = jp.pid
    proc = jp._pool._processes[pid]
    os.kill(pid, signal.SIGKILL)
    assert ended(proc) == -signal.SIGKILL


def test_a_helper_that_died_while_idle_is_replaced_and_the_next_job_runs(compute, helper, monkeypatch):
    """Killed between jobs, the helper left its pool broken: the next job used to fail at once (and every one
    after it on that worker thread).  The job did not kill it, so it runs in a new helper."""
    old = helper.pid
    _kill(helper)
    assert _run(helper, monkeypatch, _steps, 1) == ({"session": 1}, {})
    assert helper.pid not in (None, old)
    assert _run(helper, monkeypatch, _steps, 2) == ({"session": 2}, {})


def test_a_helper_killed_under_a_job_fails_that_job_and_the_next_runs(compute, helper, monkeypatch):
    def kill_at_start(stage, fraction):
        if stage == "started":
            _kill(helper)

    with pytest.raises(compute.HelperDied):
        _run(helper, monkeypatch, _sleeps, 1, kill_at_start)
    assert _run(helper, monkeypatch, _steps, 2) == ({"session": 2}, {})


def test_a_job_whose_progress_relay_raises_leaves_no_work_behind(compute, helper, monkeypatch):
    """The job thread's progress write raises (the job was superseded, the database failed): the helper must
    not go on with that job — the next job would wait behind it and be told its progress."""
    class Superseded(RuntimeError):
        pass

    calls = []

    def superseded_at_second(stage, fraction):
        calls.append(stage)
        if len(calls) == 2:
            raise Superseded(stage)

    old = helper.pid
    with pytest.raises(Superseded):
        _run(helper, monkeypatch, _steps, 1, superseded_at_second)
    seen = []
    assert _run(helper, monkeypatch, _steps, 2, lambda st, f: seen.append(st)) == ({"session": 2}, {})
    assert seen == [f"s2-{i}" for i in range(10)]
    assert helper.pid != old


def test_shutdown_stops_the_helper_under_a_job_and_the_job_is_not_failed(compute, helper, monkeypatch):
    """``shutdown`` used to leave the helper computing, and the interpreter's exit waited for its job.  Now the
    helper is terminated and the job thread is told :class:`HelperStopped` (the job resumes at the next start)."""
    monkeypatch.setattr(compute, "_compute_here", _sleeps)
    started, outcome = threading.Event(), []

    def job():
        try:
            helper.run(lambda st, f: started.set(), None, None, "en", 1, None)
        except BaseException as exc:  # noqa: BLE001 — what the job thread is told
            outcome.append(exc)

    t = threading.Thread(target=job, daemon=True)
    t.start()
    assert started.wait(120)
    proc = helper._pool._processes[helper.pid]
    helper.shutdown()
    t.join(120)
    assert not t.is_alive()
    assert [type(e) for e in outcome] == [compute.HelperStopped]
    assert ended(proc) is not None
    assert helper._progress.closed and helper._progress_w.closed
