"""Ingestion fuzzed with Hypothesis: one malformed file per example, issue 3's bad-input contract checked.

Start: a valid session made by the project's simulator (:func:`app.pipeline.demo.simulate_session`, 5 cycles), its
recordings shortened to their first :data:`KEEP_S` seconds so one load costs tens of milliseconds, written
once per module as MetaBase CSV, thesis Excel and generic CSV.  Each example copies one of them into a
fresh folder, applies one mutation of a named kind (:data:`ingestion_fuzz_kinds.KINDS`, Hypothesis
choosing the file, row, cell and garbage) and loads the folder.  The outcome must be one of:

* the session loads — then it is sane: 8 recordings and the task pair on uniform 100 Hz grids, arrays of
  the right shapes, nothing infinite, every stream with valid rows, magnitudes in the project units'
  plausible ranges (``must_load`` kinds, harmless variations of real exports, have to end here);
* :class:`IngestionError` whose message names the mutated file and says what to do.

Never another exception (a numpy ``RuntimeWarning`` counts as one), and nothing written in the folder.
``derandomize=True`` and no example database: CI runs the same examples every time.
"""

from __future__ import annotations

import hashlib
import re
import shutil
import uuid
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.pipeline.ingestion import IngestionError, load_session
from ingestion_fuzz_kinds import KINDS
from ingestion_fuzz_phyphox import write_phyphox_session
from ingestion_fuzz_vendors import write_vendor_session

#: seconds of each simulated recording kept (the figure-eight still turns enough for the gyro-unit check)
KEEP_S = 8.0
EXAMPLES_PER_KIND = 6
#: an error message "says what to do" when it has one of these imperative verbs
ADVICE = re.compile(r"\b(export|fix|record|save|check|correct|use|remove|keep|list|name|give|delete|add|copy|"
                    r"rename|process)\b", re.IGNORECASE)


def _shortened(session, keep_s: float):
    recs = {}
    for key, streams in session.recordings.items():
        t_first = min(t[0] for t, _ in streams.values())
        recs[key] = {k: (t[t < t_first + keep_s], v[t < t_first + keep_s]) for k, (t, v) in streams.items()}
    return replace(session, recordings=recs)


@pytest.fixture(scope="module")
def sessions(tmp_path_factory) -> dict[str, Path]:
    """The valid session in each input format (written once per module)."""
    from app.pipeline.demo import simulate_session, write_session

    sim = _shortened(simulate_session(seed=3, side="right", n_cycles=5), KEEP_S)
    root = tmp_path_factory.mktemp("fuzz_sessions")
    out = {}
    for fmt in ("metabase", "generic", "xlsx"):
        write_session(root / fmt, sim, fmt)
        out[fmt] = root / fmt
    for fmt in ("xsens", "shimmer", "opal", "sensorlogger"):
        out[fmt] = write_vendor_session(root / fmt, sim.recordings, fmt)
    out["phyphox"] = write_phyphox_session(root / "phyphox", sim.recordings)
    return out


def _snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): (hashlib.sha1(p.read_bytes()).hexdigest() if p.is_file() else "dir")
            for p in sorted(folder.rglob("*"))}


def _assert_sane(session) -> None:
    assert len(session.recordings) == 8
    for rec in [*session.recordings.values(), *session.task_pair()]:
        n = len(rec.t_s)
        assert rec.fs_hz == 100.0 and n >= 100
        assert np.allclose(np.diff(rec.t_s), 1.0 / rec.fs_hz)
        for name in ("acc", "gyr", "mag"):
            x = getattr(rec, name)
            assert x.shape == (n, 3) and x.dtype == np.float64 and not np.isinf(x).any(), name
            assert np.isfinite(x).all(axis=1).any(), f"{name} has no valid row"
        norm = {k: np.linalg.norm(getattr(rec, k)[np.isfinite(getattr(rec, k)).all(axis=1)], axis=1)
                for k in ("acc", "gyr", "mag")}
        mag_lo, mag_hi = (0.3, 3.0) if rec.mag_normalised else (5.0, 1000.0)
        assert 4.0 <= np.median(norm["acc"]) <= 25.0 and mag_lo <= np.median(norm["mag"]) <= mag_hi
        assert norm["gyr"].max() <= 40.0
        for f in rec.source["files"]:
            assert Path(f).parent == session.folder
    thigh, shank = session.task_pair()
    assert np.array_equal(thigh.t_s, shank.t_s)


def _check_outcome(kind: str, folder: Path, touched: tuple[Path, ...]) -> str:
    """Load ``folder``; assert the contract; return ``"loaded"`` or ``"refused"``."""
    before = _snapshot(folder)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            session = load_session(folder)
    except IngestionError as exc:
        msg = str(exc)
        assert not KINDS[kind].must_load, f"{kind} is harmless but was refused: {msg}"
        assert any(p.name in msg for p in touched), f"the message does not name {[p.name for p in touched]}: {msg}"
        assert ADVICE.search(msg), f"the message does not say what to do: {msg}"
        outcome = "refused"
    else:
        _assert_sane(session)
        outcome = "loaded"
    assert _snapshot(folder) == before, "loading wrote into the session folder"
    return outcome


def test_the_table_has_at_least_30_kinds_each_described():
    assert len(KINDS) >= 30
    assert all(k.what and k.fmt in ("metabase", "generic", "xlsx", "xsens", "shimmer", "opal", "sensorlogger",
                                    "phyphox") for k in KINDS.values())
    assert len(KINDS) >= 79           # 58 before issue 14, its spreadsheet mangling, the new formats, phyphox, the
    #                                   phones' metadata (device ids) and session.json "split"


@pytest.mark.parametrize("fmt", ["metabase", "generic", "xlsx", "xsens", "shimmer", "opal", "sensorlogger",
                                 "phyphox"])
def test_the_unmutated_sessions_load(sessions, fmt):
    """Without this, a refusal could be the starting session's fault rather than the mutation's."""
    assert _check_outcome("utf8_bom", sessions[fmt], ()) == "loaded"


@pytest.mark.parametrize("kind", sorted(KINDS))
@settings(max_examples=EXAMPLES_PER_KIND, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_malformed_file(sessions, tmp_path, kind, data):
    folder = tmp_path / uuid.uuid4().hex
    shutil.copytree(sessions[KINDS[kind].fmt], folder)
    try:
        pristine = _snapshot(folder)
        touched = KINDS[kind].mutate(folder, data.draw)
        assert _snapshot(folder) != pristine, f"{kind}: the mutation changed nothing"
        _check_outcome(kind, folder, touched)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
