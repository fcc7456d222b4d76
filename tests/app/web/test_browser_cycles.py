"""Per-cycle inspection and the clinician's choice of cycles (static/views/cycles.js), in real Chromium, in Spanish.

The demo session (simulated, 5 step-up cycles, MetaBase files) is uploaded and processed through the API.  The
results page shows one row and one flexion curve (plotly's SVG trace) per detected cycle, with the numbers
results.json holds; the technical notes (the demo's stream tails cut at alignment) sit folded in their own section,
not among the clinical warnings.  The clinician ticks cycle 2 with a reason and asks for the analysis again: the
page follows the job and opens the new analysis, whose results.json records who excluded which cycle and why, whose
row says "excluded by the clinician" apart from the pipeline's rejections, and whose statistics leave it out; the
earlier analysis is superseded and the audit log holds the request.  Unticking it includes it again.  Texts come
from static/i18n/es.json; the screenshot of the cycles chart is looked at (the excluded curve drawn grey)."""

from __future__ import annotations


import numpy as np
import pytest
from screens import look_at_widths, rgb
from test_browser_e2e import csrf_header, PROCESS_WAIT_MS, _tables, log_in, open_page, server, slow_expect  # noqa: F401

from app.pipeline.demo import simulate_session, write_session

N_CYCLES = 5
EXCLUDED_GREY = (0x8A, 0x8F, 0x98)  # cycles.js COLOURS.excluded


@pytest.fixture(scope="module")
def demo_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cycles-demo")
    paths = write_session(folder, simulate_session(seed=11, side="right", n_cycles=N_CYCLES))
    return [{"name": p.name, "mimeType": "text/csv", "buffer": p.read_bytes()} for p in sorted(paths)
            if p.suffix == ".csv"]


def uploaded_session(context, base: str, files: list[dict], external_id: str, side: str = "right") -> int:
    """A new patient's session with ``files`` uploaded through the API (not processed) with the logged-in browser's
    cookie and CSRF token: its id."""
    api = f"{base}/api/v1"
    csrf = csrf_header(context, api)
    pid = context.request.post(f"{api}/patients", data={"external_id": external_id, "side": side},
                               headers=csrf).json()["id"]
    sid = context.request.post(f"{api}/patients/{pid}/sessions", data={"step_height_m": 0.17},
                               headers=csrf).json()["id"]
    for f in files:
        r = context.request.post(f"{api}/sessions/{sid}/recordings", headers=csrf, multipart={"files": f})
        assert r.status == 201, r.text()
    return sid


def processed_session(context, page, base: str, files: list[dict], external_id: str, side: str,
                      lang: str) -> tuple[int, int]:
    """:func:`uploaded_session`, then processed: ``(session id, analysis id)``."""
    api = f"{base}/api/v1"
    sid = uploaded_session(context, base, files, external_id, side)
    csrf = csrf_header(context, api)
    job_id = context.request.post(f"{api}/sessions/{sid}/process", data={"lang": lang}, headers=csrf).json()["job_id"]
    while (job := context.request.get(f"{api}/jobs/{job_id}").json())["status"] not in ("done", "failed"):
        page.wait_for_timeout(500)
    assert job["status"] == "done", job
    return sid, job["analysis_id"]


def _next_analysis(page, previous: int) -> int:
    """Wait until the page opened an analysis other than ``previous`` (the results page follows its job), its id."""
    for _ in range(PROCESS_WAIT_MS // 250):
        if "analysis_id=" in page.url and not page.url.endswith(f"analysis_id={previous}"):
            return int(page.url.split("analysis_id=")[1])
        page.wait_for_timeout(250)
    raise AssertionError(f"no new analysis opened: {page.url}")


def _grey_pixels(png: bytes) -> int:
    return int((np.abs(rgb(png) - np.array(EXCLUDED_GREY)).sum(axis=2) <= 12).sum())


def test_cycles_shown_excluded_with_a_reason_reprocessed_and_included_again(browser, server, slow_expect,  # noqa: F811
                                                                            demo_files):
    es = _tables()["es"]
    context, page, errors = open_page(browser, "es-ES", height=1000)
    try:
        log_in(page, server)
        slow_expect(page.locator("h1")).to_have_text(es["patients.title"])
        api = f"{server}/api/v1"
        sid, first = processed_session(context, page, server, demo_files, "ES-CYCLES", "right", "es")
        r = context.request.get(f"{api}/sessions/{sid}/results").json()
        per_cycle = r["cycles"]["per_cycle"]
        assert len(per_cycle) == r["cycles"]["detected"] == N_CYCLES and r["cycles"]["excluded"] == []
        assert r["quality"]["technical_notes"] and all(w["code"] == "ingestion_note"
                                                       for w in r["quality"]["technical_notes"])
        assert not [w for w in r["quality"]["warnings"] if w["code"] == "ingestion_note"]

        page.goto(f"{server}/#/sessions/{sid}")
        table = page.locator("#cycles-table-only")
        slow_expect(table.locator("tbody tr")).to_have_count(N_CYCLES)
        chart = page.locator("#cycles-chart-only")
        chart.scroll_into_view_if_needed()  # drawn when near the view
        slow_expect(chart.locator(".scatterlayer .trace")).to_have_count(N_CYCLES)
        row2 = table.locator("tr[data-cycle='2']")
        flex2 = per_cycle[1]["rom_deg"]["flexion"]["range"]
        slow_expect(row2).to_contain_text(f"{flex2:.1f}".replace(".", ","))
        slow_expect(row2).to_contain_text(es["cycles.accepted"])
        # technical notes: their own folded section, none of them among the warnings
        notes = page.locator("details#technical-notes")
        slow_expect(notes).to_be_attached()
        assert notes.get_attribute("open") is None
        slow_expect(notes.locator("summary")).to_have_text(
            es["results.technical_notes"].format(n=len(r["quality"]["technical_notes"])))
        assert page.locator("#warnings li[data-code=ingestion_note]").count() == 0

        # exclude cycle 2 with a reason, and analyse again
        assert page.locator("#cycles-reprocess").is_disabled()
        page.locator("#exclude-only-2").check()
        page.locator("#reason-only-2").fill("tropezó al subir")
        page.locator("#cycles-reprocess").click()
        second = _next_analysis(page, first)
        row2 = page.locator("#cycles-table-only tr[data-cycle='2']")
        slow_expect(row2).to_contain_text(es["cycles.excluded"].split(" (")[0])
        slow_expect(row2).to_contain_text("tropezó al subir")
        slow_expect(row2).to_contain_text("admin@clinic.test")
        slow_expect(page.locator("#exclude-only-2")).to_be_checked()
        # looked at: the excluded cycle's row, its reason and who excluded it
        look_at_widths(page, row2, page.locator("#reason-only-2"))
        page.locator("#cycles-chart-only").scroll_into_view_if_needed()
        slow_expect(page.locator("#cycles-chart-only .scatterlayer .trace")).to_have_count(N_CYCLES)
        page.wait_for_timeout(500)  # plotly's transition
        assert _grey_pixels(page.locator("#cycles-chart-only").screenshot()) > 50  # the excluded curve, grey
        # the warnings list names no clinician's exclusion as a rejection
        assert page.locator("#warnings", has_text="tropezó").count() == 0

        r2 = context.request.get(f"{api}/sessions/{sid}/results").json()
        assert r2["cycles"]["accepted"] == r["cycles"]["accepted"] - 1
        assert [(e["cycle"], e["reason"], e["by"]) for e in r2["cycles"]["excluded"]] == \
            [(2, "tropezó al subir", "admin@clinic.test")]
        assert {(x["index"], x["reason"]) for x in r2["cycles"]["rejected"]} >= {(1, "excluded_by_clinician")}
        assert 1 not in r2["cycles"]["accepted_indices"]
        session = context.request.get(f"{api}/sessions/{sid}").json()
        by_id = {a["id"]: a for a in session["analyses"]}
        assert by_id[first]["superseded_at"] is not None and by_id[second]["superseded_at"] is None
        assert context.request.get(f"{api}/sessions/{sid}/results?analysis_id={first}").headers[
            "x-analysis-status"] == "superseded"
        events = context.request.get(f"{api}/audit", params={"limit": 50}).json()
        items = events["items"] if isinstance(events, dict) else events
        job = next(j for j in session["jobs"] if j["analysis_id"] == second)
        # the audit names the job and the cycles; the reasons are the job's (an audit detail is short)
        assert any(e["action"] == "process" and f"job {job['id']}: cycles excluded: 2;" in (e["detail"] or "")
                   for e in items), items
        assert [(e["cycle"], e["reason"]) for e in job["cycle_exclusions"]] == [(2, "tropezó al subir")]

        # the old analysis: its cycles cannot be chosen any more
        page.goto(f"{server}/#/sessions/{sid}?analysis_id={first}")
        slow_expect(page.locator("#cycles-locked")).to_have_text(es["cycles.superseded"])

        # include it again
        page.goto(f"{server}/#/sessions/{sid}")
        slow_expect(page.locator("#exclude-only-2")).to_be_checked()
        page.locator("#exclude-only-2").uncheck()
        page.locator("#cycles-reprocess").click()
        _next_analysis(page, second)
        slow_expect(page.locator("#cycles-table-only tr[data-cycle='2']")).to_contain_text(es["cycles.accepted"])
        r3 = context.request.get(f"{api}/sessions/{sid}/results").json()
        assert r3["cycles"]["excluded"] == [] and r3["cycles"]["accepted"] == r["cycles"]["accepted"]
        assert r3["rom_deg"] == r["rom_deg"]  # the same cycles, the same numbers
        assert not errors, errors
    finally:
        context.close()
