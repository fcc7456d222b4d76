"""File names in any script and odd multipart framing never answer 500 (issue 16, finding 6).

The bodies are built by hand, byte by byte (a test client's form encoder would escape or re-encode the names),
as a browser sends them: the file name as raw UTF-8 inside ``Content-Disposition`` (RFC 7578 §4.2).
"""

from __future__ import annotations

import pytest

from web_helpers import clinic_token, make_settings, new_session

CSV = b"time,acc_x\n0,1\n"


def _body(boundary: bytes, filename: bytes, data: bytes = CSV) -> bytes:
    return (b"--" + boundary + b'\r\nContent-Disposition: form-data; name="files"; filename="' + filename
            + b'"\r\nContent-Type: text/csv\r\n\r\n' + data + b"\r\n--" + boundary + b"--\r\n")


@pytest.fixture(scope="module")
def upload(tmp_path_factory):
    """``post(body, boundary) -> response`` against one session of a live app (module-wide)."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path_factory.mktemp("names") / "data")
    h = clinic_token(settings, "Names")
    with TestClient(create_app(settings)) as client:
        _, sid = new_session(client, h)

        def post(body: bytes, boundary: bytes):
            ctype = b"multipart/form-data; boundary=" + boundary
            return client.post(f"/api/v1/sessions/{sid}/recordings", content=body,
                               headers=h | {"content-type": ctype.decode("latin-1")})

        yield post


@pytest.mark.parametrize("name", [
    "Łódź-krok.csv",                 # Polish: outside Latin-1
    "βήμα-μηρός.csv",                # Greek
    "步骤-大腿.csv",                  # Chinese
    "paso-🦵-muslo.csv",             # emoji (outside the BMP)
    "\u200fשלב-ירך.csv",             # Hebrew with a right-to-left mark in front
    "خطوة-فخذ.csv",                  # Arabic
])
def test_file_names_in_any_script_are_stored_as_sent(upload, name):
    r = upload(_body(b"b0undary", name.encode("utf-8")), b"b0undary")
    assert r.status_code == 201, r.text
    assert [x["file_name"] for x in r.json()["recordings"]] == [name]


def test_a_latin1_name_from_an_old_client_is_read_as_latin1(upload):
    r = upload(_body(b"b0undary", "café-paso.csv".encode("latin-1")), b"b0undary")
    assert r.status_code == 201, r.text
    assert r.json()["recordings"][0]["file_name"] == "café-paso.csv"


def test_bidirectional_overrides_in_a_name_are_refused_in_three_languages(upload):
    name = "paso-\u202evsc.exe"  # shown as "paso-exe.csv"
    r = upload(_body(b"b0undary", name.encode("utf-8")), b"b0undary")
    assert r.status_code == 400, r.text
    body = r.json()
    assert body["code"] == "request.file_name_controls" and set(body["message"]) == {"es", "en", "pt"}


def test_a_5000_character_boundary_answers_400(upload):
    boundary = b"x" * 5000
    r = upload(_body(boundary, b"a.csv"), boundary)
    assert r.status_code == 400, r.text
    assert r.json()["code"] == "request.boundary_too_long" and "5000" in r.json()["detail"]


def test_a_71_character_boundary_is_refused_and_70_taken(upload):
    assert upload(_body(b"y" * 71, b"b71.csv"), b"y" * 71).status_code == 400
    assert upload(_body(b"y" * 70, b"b70.csv"), b"y" * 70).status_code == 201


@pytest.mark.parametrize("body", [
    b"--b0undary\r\nContent-Disposition form-data\r\n\r\nx\r\n--b0undary--\r\n",   # header without a colon
    b"--b0undaryXX\r\n",                                                               # broken boundary line
])
def test_malformed_bodies_answer_400_not_500(upload, body):
    r = upload(body, b"b0undary")
    assert r.status_code == 400, r.text
