"""The recordings' date the reports print (app.pipeline.results.recorded_dates, issue 17 §3): the local day when the
format gives local time (MetaBase's file name carries the phone's local start), else the UTC day of the epoch time
stamps, labelled UTC.  The truth is the simulated session's own clock: 2026-11-22 10:00 UTC
(:data:`app.pipeline.demo.EPOCH0_S`), written by a phone 14 h east of Greenwich, so the local day is the 23rd."""

from __future__ import annotations

import datetime as dt

from app.pipeline.demo import EPOCH0_S, simulate_session
from app.pipeline.ingestion import load_session
from app.pipeline.ingestion.writers import write_session_metabase
from app.pipeline.results import recorded_dates
from reports.labels import recorded_text
from reports.model import Patient


def test_a_metabase_recording_is_dated_by_its_local_day_not_the_utc_one(tmp_path):
    truth = simulate_session(seed=5, side="right", n_cycles=2)
    write_session_metabase(tmp_path, truth.recordings, lang="es", dialect="epoc", time_sep=".", utc_offset_h=14.0,
                           manifest={"side": "right"}, patient_id="DEMO-001", date_ddmmyyyy="23112026")
    utc_day = dt.datetime.fromtimestamp(EPOCH0_S, tz=dt.timezone.utc).date().isoformat()
    local_day = dt.datetime.fromtimestamp(EPOCH0_S + 14 * 3600, tz=dt.timezone.utc).date().isoformat()
    assert (utc_day, local_day) == ("2026-11-22", "2026-11-23")
    assert recorded_dates(load_session(tmp_path)) == (local_day, local_day, "")


def test_a_utc_day_is_labelled_utc():
    p = Patient(recorded="2026-11-22", recorded_zone="UTC")
    assert recorded_text(p, "es") == "22/11/2026 UTC" and recorded_text(p, "en") == "2026-11-22 UTC"
    assert recorded_text(Patient(recorded="2026-11-22"), "pt") == "22/11/2026"
