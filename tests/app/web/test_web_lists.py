"""Lists a page at a time and the exact lookup by identifier (issue 17, §1; :mod:`app.web.paging`).

The old list ignored ``limit`` and had no total, and the only lookup was the search box's substring match:
"MRN-77" found MRN-778899, a wrong-patient risk for a program that takes the first hit.
"""

from __future__ import annotations

import pytest
from web_helpers import clinic_token, make_settings

SYSTEM = "urn:oid:2.16.724.4.9.10.2"


@pytest.fixture
def mrn_client(tmp_path):
    """An app whose clinic's record numbers live in :data:`SYSTEM` (``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM``)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data", CHAKAMO_PATIENT_IDENTIFIER_SYSTEM=SYSTEM)
    with TestClient(create_app(settings)) as c:
        yield c, settings


def _walk(client, url: str, h: dict, params: dict) -> tuple[list[dict], list[int]]:
    """Every page of ``url`` by following ``Link: rel="next"``; the rows and each page's X-Total-Count."""
    rows, totals = [], []
    r = client.get(url, params=params, headers=h)
    while True:
        assert r.status_code == 200, r.text
        rows += r.json()
        totals.append(int(r.headers["x-total-count"]))
        if "link" not in r.headers:
            assert "x-next-cursor" not in r.headers
            return rows, totals
        link = r.headers["link"]
        assert link.endswith('>; rel="next"') and "cursor=" + r.headers["x-next-cursor"] in link
        r = client.get(link[1:link.index(">")], headers=h)


def test_identifier_lookup_is_exact_and_knows_its_system(mrn_client):
    client, settings = mrn_client
    h = clinic_token(settings, "Hospital MRN")
    for mrn in ("MRN-778899", "MRN-77", "mrn-77", "X-MRN-77"):
        assert client.post("/api/v1/patients", json={"external_id": mrn, "side": "left"}, headers=h).status_code == 201
    other = clinic_token(settings, "Other clinic")
    assert client.post("/api/v1/patients", json={"external_id": "MRN-77", "side": "left"}, headers=other).status_code == 201

    def ids(**params):
        r = client.get("/api/v1/patients", params=params, headers=h)
        assert r.status_code == 200, r.text
        assert int(r.headers["x-total-count"]) == len(r.json())
        return [p["external_id"] for p in r.json()]

    assert ids(identifier="MRN-77") == ["MRN-77"]
    assert ids(identifier=f"{SYSTEM}|MRN-77") == ["MRN-77"]
    assert ids(identifier="urn:oid:1.2.3|MRN-77") == []       # another hospital's namespace
    assert ids(identifier="|MRN-77") == []                     # "no system": ours has one
    assert ids(identifier="MRN-7") == []
    assert sorted(ids(q="MRN-77")) == sorted(["MRN-778899", "MRN-77", "mrn-77", "X-MRN-77"])  # the search box


def test_identifier_without_a_configured_system(client, settings):
    h = clinic_token(settings, "Hospital")
    for mrn in ("MRN-778899", "MRN-77"):
        client.post("/api/v1/patients", json={"external_id": mrn, "side": "left"}, headers=h)
    get = lambda v: [p["external_id"] for p in client.get("/api/v1/patients", params={"identifier": v}, headers=h).json()]  # noqa: E731
    assert get("|MRN-77") == ["MRN-77"] and get("MRN-77") == ["MRN-77"] and get(f"{SYSTEM}|MRN-77") == []


def test_patients_and_sessions_come_in_cursor_pages_with_totals(client, settings):
    h = clinic_token(settings, "Hospital pages")
    made = []
    for i in range(7):
        r = client.post("/api/v1/patients", json={"external_id": f"P-{i}", "side": "right"}, headers=h)
        made.append(r.json()["id"])
    rows, totals = _walk(client, "/api/v1/patients", h, {"limit": 3})
    assert [p["id"] for p in rows] == sorted(made, reverse=True)  # newest first, each once
    assert totals == [7, 7, 7]
    everything = client.get("/api/v1/patients", headers=h)  # no limit: the whole list (the UI's)
    assert len(everything.json()) == 7 and "link" not in everything.headers

    # a patient created between two pages is neither repeated nor the cause of a skip (keyset, not offset)
    first = client.get("/api/v1/patients", params={"limit": 3}, headers=h)
    client.post("/api/v1/patients", json={"external_id": "P-new", "side": "right"}, headers=h)
    rest, _ = _walk(client, "/api/v1/patients", h, {"limit": 3, "cursor": first.headers["x-next-cursor"]})
    assert [p["id"] for p in first.json() + rest] == sorted(made, reverse=True)

    bad = client.get("/api/v1/patients", params={"cursor": "not-a-cursor!"}, headers=h)
    assert bad.status_code == 400 and bad.json()["code"] == "request.cursor_invalid"
    assert bad.headers["content-type"] == "application/problem+json"
    assert client.get("/api/v1/patients", params={"limit": 0}, headers=h).status_code == 422

    pid = made[0]
    dates = ["2026-01-05", "2026-03-01", "2026-01-05", "2025-12-24", "2026-03-01"]
    sids = [client.post(f"/api/v1/patients/{pid}/sessions", json={"date": d}, headers=h).json()["id"] for d in dates]
    rows, totals = _walk(client, f"/api/v1/patients/{pid}/sessions", h, {"limit": 2})
    expected = [s for _, s in sorted(zip(dates, sids), reverse=True)]  # by date, then creation, newest first
    assert [s["id"] for s in rows] == expected and totals == [5, 5, 5]
    bad = client.get(f"/api/v1/patients/{pid}/sessions", params={"cursor": "WzFd"}, headers=h)  # [1]: not a key
    assert bad.status_code == 400
