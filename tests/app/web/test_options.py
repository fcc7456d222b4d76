"""``GET /api/v1/options``: every option list once (app.choices), the same lists in the CLI, the API's schemas
and the estimator registries."""

from __future__ import annotations

import argparse
import math

import pytest

from app import choices


def _subparser(name: str) -> argparse.ArgumentParser:
    from app.cli.main import _build_parser

    parser = _build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


def _choices_of(parser: argparse.ArgumentParser, flag: str) -> tuple:
    return tuple(next(a for a in parser._actions if flag in a.option_strings).choices)


def test_options_need_a_caller_and_list_every_option_once(client, settings):
    from web_helpers import clinic_token

    assert client.get("/api/v1/options").status_code == 401
    r = client.get("/api/v1/options", headers=clinic_token(settings, "C", role="read_only"))
    assert r.status_code == 200, r.text
    body = r.json()
    assert set(body) == {"filters", "tasks", "languages", "calibrations", "angle_conventions", "headings", "sides",
                         "sexes", "token_scopes", "audit_actions", "measure_ranges", "roles", "token_max_days",
                         "live_checks"}
    from app.web.audit import ACTIONS

    # one definition each (app.choices), which the patient form and the admin pages read from here
    assert body["measure_ranges"] == {k: {"min": lo, "max": hi} for k, (lo, hi) in choices.MEASURE_RANGES.items()}
    assert body["roles"] == list(choices.USER_ROLE_NAMES) and body["token_max_days"] == choices.TOKEN_MAX_DAYS

    assert body["sexes"] == list(choices.SEX_NAMES)
    # the recording page's live checks read their thresholds from here: the pipeline's still window and limits as
    # its docstrings state them (estimators.knee: 5 s, 0.05 rad/s, 0.3 m/s²), its 3 samples in each of the 20
    # direction cells and its warning below 75 % of them (estimators.magnetometer), and the live-only values
    # (app/choices.py: 15 µT; 0.3 s, 60 °/s, 20 °/s)
    live = body["live_checks"]
    assert live["stillness"] == {"window_s": 5.0, "max_gyr_sd_rad_s": 0.05, "max_acc_sd_m_s2": 0.3}
    assert live["coverage"] == {"min_cell_samples": 3, "complete_fraction": 0.75, "min_field_ut": 15.0}
    assert type(live["coverage"]["min_cell_samples"]) is int                  # a count, not 3.0
    assert live["cycles"] == {"average_s": 0.3, "rise_rad_s": pytest.approx(math.pi / 3),
                              "fall_rad_s": pytest.approx(math.pi / 9)}
    assert body["token_scopes"] == list(choices.TOKEN_SCOPES) and body["audit_actions"] == list(ACTIONS)
    for key in choices.OPTION_LISTS:
        items = body[key]
        assert [i["name"] for i in items] == list(choices.names(choices.OPTION_LISTS[key])), key
        assert sum(i["default"] for i in items) == 1, f"{key}: exactly one default"
        assert all(i["label"] for i in items), key
    # the lists are the estimators' and the reports' registries, not copies typed again
    from estimators.motor_task import TASK_NAMES
    from estimators.orientation import DEFAULT_METHOD, METHODS
    from reports.i18n import LANGUAGES

    assert [f["name"] for f in body["filters"]] == list(METHODS)
    assert next(f["name"] for f in body["filters"] if f["default"]) == DEFAULT_METHOD
    assert [t["name"] for t in body["tasks"]] == list(TASK_NAMES)
    assert all(t["phases"] for t in body["tasks"])
    assert [lang["name"] for lang in body["languages"]] == list(LANGUAGES)


def test_the_cli_offers_the_same_choices():
    proc = _subparser("process")
    assert _choices_of(proc, "--filter") == choices.FILTER_NAMES
    assert _choices_of(proc, "--task") == choices.TASK_NAMES
    assert _choices_of(proc, "--lang") == choices.LANGUAGE_NAMES
    assert _choices_of(proc, "--calibration") == choices.CALIBRATION_NAMES
    assert _choices_of(proc, "--angles") == choices.ANGLE_CONVENTION_NAMES
    assert _choices_of(_subparser("reprocess"), "--filter") == choices.FILTER_NAMES


@pytest.mark.parametrize("task", _choices_of(_subparser("process"), "--task"))
def test_the_api_accepts_every_task_the_cli_accepts(client, settings, task):
    from web_helpers import clinic_token

    h = clinic_token(settings, "C")
    pid = client.post("/api/v1/patients", json={"external_id": "P-1", "side": "left"}, headers=h).json()["id"]
    r = client.post(f"/api/v1/patients/{pid}/sessions", json={"task": task}, headers=h)
    assert r.status_code == 201, r.text
    r = client.get(f"/api/v1/sessions/{r.json()['id']}", headers=h)
    assert r.status_code == 200 and r.json()["task"] == task, r.text


def test_the_api_refuses_a_task_it_does_not_know(client, settings):
    from web_helpers import clinic_token

    h = clinic_token(settings, "C")
    pid = client.post("/api/v1/patients", json={"external_id": "P-1", "side": "left"}, headers=h).json()["id"]
    r = client.post(f"/api/v1/patients/{pid}/sessions", json={"task": "moonwalk"}, headers=h)
    assert r.status_code == 422 and "task" in r.json()["detail"], r.text
    body = r.json()   # like every refusal: a code, its params and the sentence in es/en/pt naming the field
    assert body["code"] == "request.invalid" and r.headers["X-ChakaMo-Code"] == "request.invalid"
    assert set(body["message"]) == {"es", "en", "pt"} and all("task" in t for t in body["message"].values())
    assert "Corrija" in body["message"]["es"] and "Corrija" in body["message"]["pt"]
    missing = client.get(f"/api/v1/patients/{pid + 999}", headers=h)   # a store refusal (404): coded, 3 languages
    assert missing.status_code == 404 and missing.json()["code"] == "store.no_patient", missing.text
    assert "paciente" in missing.json()["message"]["es"] and "paciente" in missing.json()["message"]["pt"]
    assert all(repr(t) in r.json()["detail"] for t in choices.TASK_NAMES), r.text


def test_the_openapi_document_lists_the_filters_and_tasks(client):
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    filt = schemas["ProcessIn"]["properties"]["filter"]
    enum = next(s["enum"] for s in filt["anyOf"] if "enum" in s)
    assert tuple(enum) == choices.FILTER_NAMES
    assert tuple(schemas["SessionIn"]["properties"]["task"]["enum"]) == choices.TASK_NAMES


def test_the_heading_chosen_in_a_processing_request_reaches_the_results(client, settings, demo_dir):
    """``POST /process {"heading": ...}`` (issue 13 §2: selectable in the API and the UI as on the CLI): the job runs
    with it and results.json says so; a heading the server does not know is refused with the valid ones."""
    from web_helpers import clinic_token, demo_files, new_session, wait_job

    h = clinic_token(settings, "C")
    _, sid = new_session(client, h)
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"heading": "compass"}, headers=h)
    assert r.status_code == 422 and all(repr(x) in r.json()["detail"] for x in choices.HEADING_NAMES), r.text
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"heading": "constraint", "lang": "en"}, headers=h)
    assert r.status_code == 202, r.text
    assert wait_job(client, r.json()["job_id"], h)["status"] == "done"
    results = client.get(f"/api/v1/sessions/{sid}/results", headers=h).json()
    assert results["quality"]["heading"]["mode"] == "constraint" and results["quality"]["heading"]["used"] == "constraint"


def test_the_calibration_and_angle_convention_chosen_reach_the_results(client, settings, demo_dir):
    """``POST /process {"calibration", "angle_convention"}`` (issue 17 §4: the wizard's choices, as ``chakamo process
    --calibration / --angles``): the job records them, the pipeline runs with them and results.json says so (the
    functional calibration's segment method, the thesis' angle extraction); an unknown value is refused with the
    valid ones."""
    from web_helpers import clinic_token, demo_files, new_session, wait_job

    h = clinic_token(settings, "C")
    _, sid = new_session(client, h)
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"calibration": "magic"}, headers=h)
    assert r.status_code == 422 and all(repr(x) in r.json()["detail"] for x in choices.CALIBRATION_NAMES), r.text
    r = client.post(f"/api/v1/sessions/{sid}/process", json={"angle_convention": "xyz"}, headers=h)
    assert r.status_code == 422 and all(repr(x) in r.json()["detail"] for x in choices.ANGLE_CONVENTION_NAMES), r.text
    r = client.post(f"/api/v1/sessions/{sid}/process", headers=h,
                    json={"calibration": "functional", "angle_convention": "thesis_zyx", "lang": "en"})
    assert r.status_code == 202, r.text
    job = wait_job(client, r.json()["job_id"], h)
    assert job["status"] == "done" and (job["calibration"], job["angle_convention"]) == ("functional", "thesis_zyx")
    results = client.get(f"/api/v1/sessions/{sid}/results", headers=h).json()
    assert results["angle_method"] == "thesis_zyx"
    methods = {seg: c["method"] for seg, c in results["calibration"]["segment"].items()}
    assert methods and all("functional" in m for m in methods.values()), methods


def test_the_live_checks_schema_names_every_threshold(client):
    """The OpenAPI document lists live_checks' keys and types (a model, not a free dict of floats): the cell count
    is an integer."""
    doc = client.get("/openapi.json").json()
    schemas = doc["components"]["schemas"]
    ref = schemas["OptionsOut"]["properties"]["live_checks"]["$ref"].rsplit("/", 1)[-1]
    parts = {k: schemas[v["$ref"].rsplit("/", 1)[-1]]["properties"] for k, v in schemas[ref]["properties"].items()}
    assert {k: set(v) for k, v in parts.items()} == {
        "stillness": {"window_s", "max_gyr_sd_rad_s", "max_acc_sd_m_s2"},
        "coverage": {"min_cell_samples", "complete_fraction", "min_field_ut"},
        "cycles": {"average_s", "rise_rad_s", "fall_rad_s"}}
    assert parts["coverage"]["min_cell_samples"]["type"] == "integer"
    assert parts["stillness"]["window_s"]["type"] == "number"
