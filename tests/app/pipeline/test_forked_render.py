"""The CLI's forked render helpers (``app.pipeline.render.ForkedRenderers``) give the bytes of rendering in the
process itself, and a helper that dies or is not used costs nothing but time."""

import os
import signal
import sys

import pytest

import numpy as np

from app.pipeline.demo import simulate_session, write_session
from app.pipeline.ingestion import load_knees
from app.pipeline.process import REPORT_FILES, process_folder
from app.pipeline.render import FORK_GROUPS, ForkedRenderers, render_named
from app.pipeline.results import build_results, report_input, timeseries_npz, timeseries_npz_of

pytestmark = pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin", reason="needs os.fork")


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("forked")
    write_session(root / "session", simulate_session(seed=5, side="right", n_cycles=3))
    return root / "session"


@pytest.fixture(scope="module")
def processed(session_dir):
    """A simulated 3-cycle session processed in this process (no reports written): outcome and report input."""
    outcome, _ = process_folder(session_dir, session_dir.parent / "out", reports=False)
    return outcome, report_input(outcome, build_results(outcome))


@pytest.fixture(scope="module")
def report(processed):
    return processed[1]


def test_the_series_from_the_report_input_are_the_outcomes(processed):
    outcome, ri = processed
    assert timeseries_npz_of(ri) == timeseries_npz(outcome)


def _gone(pid: int) -> bool:
    try:
        os.waitpid(pid, os.WNOHANG)
    except ChildProcessError:
        return True
    return False


def test_the_groups_cover_every_report_file_once():
    names = [name for group in FORK_GROUPS for name in group]
    assert sorted(names) == sorted(REPORT_FILES) and len(names) == len(set(names))


def test_forked_helpers_render_the_same_bytes_as_this_process(report):
    expected = render_named(report, REPORT_FILES)
    with ForkedRenderers() as renderer:
        pid = renderer.pid
        got = renderer.render(report)
    assert set(got) == set(REPORT_FILES)
    for name in REPORT_FILES:
        assert got[name] == expected[name], name
    assert _gone(pid)  # reaped: no zombie left behind


def test_a_killed_helper_is_replaced_by_rendering_here(report):
    expected = render_named(report, ("report.html", "angles.xlsx"))
    renderer = ForkedRenderers(groups=(("report.html",), ("angles.xlsx",)))
    os.kill(renderer.pid, signal.SIGKILL)
    got = renderer.render(report)
    assert got == expected


def test_an_unused_helper_exits_when_closed():
    renderer = ForkedRenderers()
    pid = renderer.pid
    renderer.close()
    assert renderer.pid is None and _gone(pid)


def test_a_failing_artefact_fails_here_as_it_would_without_helpers(report):
    with ForkedRenderers(groups=(("report.html",), ("no-such-artefact",))) as renderer:
        with pytest.raises(ValueError, match="unknown artefact"):
            renderer.render(report)


def test_the_helper_reads_the_session_as_this_process_does(session_dir):
    (side, here), = load_knees(session_dir, expected_fs_hz=100.0).items()  # one knee: {side: Session}
    with ForkedRenderers(read=(session_dir, 100.0)) as renderer:
        assert renderer.reading
        knees = renderer.session()
        assert not renderer.reading
    assert list(knees) == [side]
    there = knees[side]
    assert there.recordings.keys() == here.recordings.keys()
    pairs = [(there.recordings[k], r) for k, r in here.recordings.items()] + list(zip(there.task, here.task))
    for a, b in pairs:
        assert (a.fs_hz, a.t0_s) == (b.fs_hz, b.t0_s)
        for field in ("t_s", "acc", "gyr", "mag"):
            assert np.array_equal(getattr(a, field), getattr(b, field), equal_nan=True), field
    assert [str(n) for n in there.notes] == [str(n) for n in here.notes]


def test_a_session_the_helper_cannot_read_is_read_here(tmp_path):
    import time

    with ForkedRenderers(read=(tmp_path / "missing", 100.0)) as renderer:
        deadline = time.monotonic() + 60.0
        while not renderer.read_failed and time.monotonic() < deadline:
            time.sleep(0.01)
        assert renderer.read_failed  # so process_folder reads it at once, without loading numba first
        assert renderer.session() is None  # and raises the user's error itself


def test_nothing_is_forked_while_other_threads_run(report):
    import threading

    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        renderer = ForkedRenderers(read=(".", 100.0))
        assert renderer.pid is None and renderer.session() is None
        assert renderer.render(report) == render_named(report, REPORT_FILES)
    finally:
        stop.set()
        other.join()
