"""The reports rendered again from a stored analysis (results.json + timeseries.npz, as the server keeps them) are the
reports the job rendered: the same PDF bytes and HTML for the same patient and report date, so an interpretation
signed later is added to exactly the report the clinician read (issue 17 §3, :mod:`app.store.signed_reports`)."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import tempfile
from pathlib import Path

import numpy as np

from app.pipeline.demo import simulate_session, write_session
from app.pipeline.process import process_folder
from app.pipeline.results import (build_results, patient_of, report_input, report_input_of_files, results_json,
                                  timeseries_npz)
from reports.html import render_html
from reports.pdf import render_pdf


def test_reports_from_the_stored_files_equal_the_jobs():
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "session"
        write_session(folder, simulate_session(seed=3, side="left", n_cycles=3))
        outcome, _ = process_folder(folder, Path(tmp) / "out", reports=False)
    results = build_results(outcome)
    ri = report_input(outcome, results)
    stored = json.loads(results_json(results))  # what the server keeps and reads back
    npz = timeseries_npz(outcome)
    recorded = stored["session"]["recorded"]
    patient = patient_of(outcome.session.manifest_data, record=stored["session"]["patient_id"],
                         date=stored["session"]["date"], side=stored["side"],
                         step_height_m=stored["session"]["step_height_m"],
                         recorded=(recorded["first"] or "", recorded["last"] or "", recorded["zone"] or ""))
    assert patient == ri.patient
    again = report_input_of_files(stored, npz, patient, ri.language)
    assert np.array_equal(again.t_s, ri.t_s) and np.array_equal(again.angles_deg, ri.angles_deg)
    day = dt.date(2026, 12, 2)
    for lang in ("es", "pt"):
        assert render_pdf(dataclasses.replace(again, language=lang), report_date=day) == \
            render_pdf(dataclasses.replace(ri, language=lang), report_date=day)
    assert render_html(again) == render_html(ri)
