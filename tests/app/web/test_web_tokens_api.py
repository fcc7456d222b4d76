"""The admin API of API tokens (``/api/v1/tokens``, :mod:`app.web.api.tokens`), behind the admin pages: an admin
creates a scoped, expiring token (its secret answered once), the API then honours it as ``chakamo tokens`` tokens
are honoured (scope refused with 403), a rotation hands a working successor and ends the old one after the grace,
a revocation ends it at once (401); a clinician, and another clinic's admin, cannot touch them; every change is in
the audit log."""

from __future__ import annotations

from web_helpers import clinic_token


def test_admin_creates_rotates_and_revokes_tokens_through_the_api(client, settings):
    admin = clinic_token(settings, "Clinic T", role="admin")
    other_admin = clinic_token(settings, "Clinic U", role="admin")
    clinician = clinic_token(settings, "Clinic T")

    assert client.get("/api/v1/tokens", headers=clinician).status_code == 403
    r = client.post("/api/v1/tokens", headers=admin, json={"label": "PACS", "role": "read_only", "expires_days": 30,
                                                           "scopes": ["patients:read"]})
    assert r.status_code == 201, r.text
    created = r.json()
    assert created["state"] == "active" and created["scopes"] == ["patients:read"] and created["token"]
    bearer = {"Authorization": f"Bearer {created['token']}"}
    assert client.get("/api/v1/patients", headers=bearer).status_code == 200
    assert client.get("/api/v1/jobs/1", headers=bearer).status_code == 403  # outside its scopes
    listed = {t["id"]: t for t in client.get("/api/v1/tokens", headers=admin).json()}
    assert "token" not in listed[created["id"]] and listed[created["id"]]["label"] == "PACS"

    # unknown scope and a lifetime out of range are refused
    assert client.post("/api/v1/tokens", headers=admin, json={"scopes": ["patients:fly"]}).status_code == 422
    assert client.post("/api/v1/tokens", headers=admin, json={"expires_days": 0}).status_code == 422

    # another clinic's admin sees a 404, never the token
    assert client.post(f"/api/v1/tokens/{created['id']}/revoke", headers=other_admin).status_code == 404
    assert created["id"] not in {t["id"] for t in client.get("/api/v1/tokens", headers=other_admin).json()}

    r = client.post(f"/api/v1/tokens/{created['id']}/rotate", headers=admin, json={"grace_hours": 0})
    assert r.status_code == 200, r.text
    new = r.json()["new"]
    assert new["scopes"] == ["patients:read"] and new["role"] == "read_only" and new["token"] != created["token"]
    assert client.get("/api/v1/patients", headers=bearer).status_code == 401       # grace 0: the old one ended
    successor = {"Authorization": f"Bearer {new['token']}"}
    assert client.get("/api/v1/patients", headers=successor).status_code == 200

    r = client.post(f"/api/v1/tokens/{new['id']}/revoke", headers=admin)
    assert r.status_code == 200 and r.json()["state"] == "revoked"
    assert client.get("/api/v1/patients", headers=successor).status_code == 401
    again = client.post(f"/api/v1/tokens/{new['id']}/revoke", headers=admin).json()
    assert again["revoked_at"] == r.json()["revoked_at"]   # revoking twice keeps the first date
    assert client.post(f"/api/v1/tokens/{new['id']}/rotate", headers=admin).status_code in (400, 409, 422)

    actions = [e["action"] for e in client.get("/api/v1/audit", headers=admin, params={"limit": 1000}).json()]
    assert actions.count("token_revoke") == 1 and actions.count("token_create") >= 2
