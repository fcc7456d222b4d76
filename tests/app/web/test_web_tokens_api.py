"""The admin API of API tokens (``/api/v1/tokens``, :mod:`app.web.api.tokens`), behind the admin pages: an admin
creates a scoped, expiring token (its secret answered once), the API then honours it as ``chakamo tokens`` tokens
are honoured (scope refused with 403), a rotation hands a working successor and ends the old one after the grace,
a revocation ends it at once (401); a clinician, and another clinic's admin, cannot touch them; every change is in
the audit log (a rotation as ``token_rotate``), never the secret.  A token never outgrows the token that made it:
a scoped or expiring admin token cannot mint an unlimited token nor create or change a user account."""

from __future__ import annotations

from web_helpers import clinic_token

PASSWORD = "a long enough pass phrase"


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
    dead = client.post(f"/api/v1/tokens/{new['id']}/rotate", headers=admin)
    assert dead.status_code in (400, 409, 422)
    assert "Administration page" in dead.text  # the web admin is told the page, not only the server's command

    audit = client.get("/api/v1/audit", headers=admin, params={"limit": 1000})
    actions = [e["action"] for e in audit.json()]
    # created: the admin's and the clinician's (chakamo tokens) and the PACS one; rotated once, not created again
    assert actions.count("token_revoke") == 1 and actions.count("token_rotate") == 1 and actions.count("token_create") == 3
    listing = client.get("/api/v1/tokens", headers=admin)
    for secret in (created["token"], new["token"]):  # answered once, then nowhere: not listed, not audited
        assert secret not in audit.text and secret not in listing.text


def _token(client, headers, **body) -> dict:
    r = client.post("/api/v1/tokens", headers=headers, json=body)
    assert r.status_code == 201, r.text
    return r.json()


def test_a_token_hands_out_no_more_than_it_holds(client, settings):
    """Tokens (create, rotate) and users (create, change, unlock) from a scoped and from an expiring admin token."""
    admin = clinic_token(settings, "Clinic V", role="admin")  # unscoped, no end: as much as an admin account
    scoped = _token(client, admin, role="admin", scopes=["users:read", "users:write", "patients:read"])
    scoped_h = {"Authorization": f"Bearer {scoped['token']}"}
    expiring = _token(client, admin, role="admin", expires_days=7)
    expiring_h = {"Authorization": f"Bearer {expiring['token']}"}

    # the reviewer's escalation: an admin token with no scopes and no end, from a scoped or an expiring one
    for h, code in ((scoped_h, "auth.grant_beyond_scopes"), (expiring_h, "auth.grant_beyond_expiry")):
        r = client.post("/api/v1/tokens", headers=h, json={"role": "admin"})
        assert r.status_code == 403 and r.headers["x-chakamo-code"] == code, r.text
    r = client.post("/api/v1/tokens", headers=scoped_h, json={"role": "admin", "scopes": ["patients:write"]})
    assert r.status_code == 403 and r.headers["x-chakamo-code"] == "auth.grant_beyond_scopes"
    r = client.post("/api/v1/tokens", headers=expiring_h, json={"role": "admin", "expires_days": 8})
    assert r.status_code == 403 and r.headers["x-chakamo-code"] == "auth.grant_beyond_expiry"
    # within its bounds it may
    _token(client, scoped_h, role="read_only", scopes=["patients:read"])
    _token(client, expiring_h, role="clinician", expires_days=6)
    # a rotation hands the same scopes and lifetime from now: an unlimited token cannot be rotated by a limited
    # one, nor an expiring token rotate itself (its successor would end later)
    r = client.post(f"/api/v1/tokens/{expiring['id']}/rotate", headers=expiring_h)
    assert r.status_code == 403 and r.headers["x-chakamo-code"] == "auth.grant_beyond_expiry"
    unlimited_id = next(t["id"] for t in client.get("/api/v1/tokens", headers=admin).json() if t["scopes"] is None
                        and t["expires_at"] is None)
    assert client.post(f"/api/v1/tokens/{unlimited_id}/rotate", headers=scoped_h).status_code == 403

    # users: an account holds its role with every scope and no end, so only an unlimited caller manages them
    for h in (scoped_h, expiring_h):
        r = client.post("/api/v1/users", headers=h, json={"email": "boss@clinic.test", "name": "B", "role": "admin",
                                                          "password": PASSWORD})
        assert r.status_code == 403, r.text
    r = client.post("/api/v1/users", headers=admin, json={"email": "clin@clinic.test", "name": "C",
                                                          "role": "clinician", "password": PASSWORD})
    assert r.status_code == 201, r.text
    uid = r.json()["id"]
    for h in (scoped_h, expiring_h):
        assert client.patch(f"/api/v1/users/{uid}", headers=h, json={"role": "admin"}).status_code == 403
        assert client.post(f"/api/v1/users/{uid}/unlock", headers=h).status_code == 403
    assert [u["role"] for u in client.get("/api/v1/users", headers=admin).json() if u["id"] == uid] == ["clinician"]
    assert "boss@clinic.test" not in client.get("/api/v1/users", headers=admin).text
    # each refusal is recorded
    denied = [e for e in client.get("/api/v1/audit", headers=admin, params={"action": "denied", "limit": 100}).json()
              if "grant beyond" in (e.get("detail") or "")]
    assert len(denied) >= 10
