"""Route-level checks with FastAPI dependency overrides: the caller is swapped without any login or token,
so each route's own role and clinic checks are exercised alone."""

from __future__ import annotations

import pytest

from app.web.api.deps import Principal, get_principal


@pytest.fixture
def as_caller(client):
    """``as_caller(clinic_id, role)``: every request of ``client`` now comes from that caller."""
    def use(clinic_id: int, role: str, name: str = "Clinic") -> None:
        client.app.dependency_overrides[get_principal] = lambda: Principal(clinic_id=clinic_id, clinic_name=name,
                                                                            role=role, via="bearer")
    yield use
    client.app.dependency_overrides.clear()


def test_roles_are_enforced_per_route(client, settings, as_caller):
    from app.cli import admin as admin_cli

    a = admin_cli.create_clinic(settings, "A")
    as_caller(a, "read_only", "A")
    r = client.post("/api/v1/patients", json={"external_id": "P1", "side": "left"})
    assert r.status_code == 403 and "clinician role" in r.json()["detail"]
    assert client.get("/api/v1/patients").status_code == 200
    as_caller(a, "clinician", "A")
    assert client.post("/api/v1/patients", json={"external_id": "P1", "side": "left"}).status_code == 201
    assert client.get("/api/v1/users").status_code == 403  # admin only
    as_caller(a, "admin", "A")
    assert client.get("/api/v1/users").status_code == 200


def test_every_query_is_scoped_to_the_callers_clinic(client, settings, as_caller):
    from app.cli import admin as admin_cli

    a, b = admin_cli.create_clinic(settings, "A"), admin_cli.create_clinic(settings, "B")
    as_caller(a, "clinician", "A")
    pid = client.post("/api/v1/patients", json={"external_id": "P1", "side": "right"}).json()["id"]
    sid = client.post(f"/api/v1/patients/{pid}/sessions", json={}).json()["id"]
    as_caller(b, "admin", "B")
    assert client.get("/api/v1/patients").json() == []
    for url in (f"/api/v1/patients/{pid}", f"/api/v1/patients/{pid}/sessions", f"/api/v1/sessions/{sid}"):
        assert client.get(url).status_code == 404, url
    assert client.post(f"/api/v1/sessions/{sid}/process", json={}).status_code == 404
    # the same external id is free in another clinic
    assert client.post("/api/v1/patients", json={"external_id": "P1", "side": "left"}).status_code == 201
