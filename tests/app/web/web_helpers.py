"""Helpers of the web application tests (imported by the tests and by conftest.py)."""

from __future__ import annotations

import time
from contextlib import contextmanager
from pathlib import Path


def make_settings(data_dir: Path, **extra):
    """Development settings on ``data_dir``, one job thread, no render process unless ``extra`` asks."""
    from app.settings import Settings

    values = {"CHAKAMO_ENV": "development", "CHAKAMO_DATA_DIR": data_dir, "CHAKAMO_WORKERS": 1,
              "CHAKAMO_RENDER_PROCESSES": 0} | extra
    return Settings(**values)


@contextmanager
def hash_slots_held():
    """Every password-hashing thread and queue place of ``app.web.security`` taken for the block (by work that
    waits, as a flood of logins would); yields how many were taken."""
    import threading

    from app.web import security

    release = threading.Event()
    futures = []
    try:
        while True:
            try:
                futures.append(security._submit(release.wait, 60))
            except security.Busy:
                break
        yield len(futures)
    finally:
        release.set()
        for f in futures:
            f.result()


def clinic_token(settings, name: str, role: str = "clinician") -> dict[str, str]:
    """Create clinic ``name`` (if new) and a token through the CLI functions; return the bearer header."""
    from app.cli import admin as admin_cli

    try:
        admin_cli.create_clinic(settings, name)
    except ValueError:
        pass
    token = admin_cli.create_token(settings, clinic=name, role=role, label="tests")
    return {"Authorization": f"Bearer {token}"}


def demo_files(demo_dir: Path) -> list[tuple[str, tuple[str, bytes, str]]]:
    return [("files", (p.name, p.read_bytes(), "text/csv")) for p in sorted(demo_dir.glob("*.csv"))]


def wait_job(client, job_id: int, headers: dict | None = None, timeout_s: float = 300.0) -> dict:
    """Poll ``GET /jobs/{id}`` until done or failed (generous: the machine is shared; nothing is timed)."""
    end = time.monotonic() + timeout_s
    job = None
    while time.monotonic() < end:
        job = client.get(f"/api/v1/jobs/{job_id}", headers=headers or {}).json()
        if job["status"] in ("done", "failed"):
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} did not finish in {timeout_s} s: {job}")


def new_session(client, headers, external_id: str = "P-1", side: str = "right") -> tuple[int, int]:
    r = client.post("/api/v1/patients", json={"external_id": external_id, "side": side}, headers=headers)
    assert r.status_code == 201, r.text
    pid = r.json()["id"]
    r = client.post(f"/api/v1/patients/{pid}/sessions", json={"step_height_m": 0.17}, headers=headers)
    assert r.status_code == 201, r.text
    return pid, r.json()["id"]


# ------------------------------------------------------------------ raw ASGI (bodies the test clients cannot send)
BOUNDARY = "chakamo-test-boundary"


def multipart(files=(), fields=(), boundary: str = BOUNDARY) -> bytes:
    """A multipart/form-data body: ``files`` as ``(name, bytes)`` in field ``files``, ``fields`` as ``(k, v)``."""
    out = b""
    for key, value in fields:
        out += (f'--{boundary}\r\nContent-Disposition: form-data; name="{key}"\r\n\r\n{value}\r\n').encode()
    for name, data in files:
        out += (f'--{boundary}\r\nContent-Disposition: form-data; name="files"; filename="{name}"\r\n'
                'Content-Type: text/csv\r\n\r\n').encode() + data + b"\r\n"
    return out + f"--{boundary}--\r\n".encode()


class AsgiCall:
    """One HTTP request driven by hand against an ASGI app: the body goes in ``chunks``; after ``pause_after``
    chunks the request waits until :meth:`resume` (``disconnect=True``: the client then goes away).
    ``status`` / ``body`` / ``json()`` after :meth:`run`; ``paused`` is set while it waits for more body."""

    def __init__(self, app, method: str, path: str, headers: dict, chunks=(), pause_after: int | None = None,
                 content_length: bool = True) -> None:
        import asyncio

        self.app, self.method, self.path = app, method, path
        self.chunks = list(chunks)
        hdrs = [(k.lower().encode(), v.encode()) for k, v in headers.items()]
        if content_length:
            hdrs.append((b"content-length", str(sum(len(c) for c in self.chunks)).encode()))
        self.headers = hdrs
        self.pause_after = pause_after
        self.paused, self._resume, self._done = asyncio.Event(), asyncio.Event(), asyncio.Event()
        self.disconnect = False
        self.status: int | None = None
        self.body = b""
        self._i = 0

    def resume(self, disconnect: bool = False) -> None:
        self.disconnect = disconnect
        self._resume.set()

    async def _receive(self):
        if self.pause_after is not None and self._i == self.pause_after:
            self.paused.set()
            await self._resume.wait()
            if self.disconnect:
                return {"type": "http.disconnect"}
        if self._i < len(self.chunks):
            self._i += 1
            return {"type": "http.request", "body": self.chunks[self._i - 1], "more_body": self._i < len(self.chunks)}
        await self._done.wait()
        return {"type": "http.disconnect"}

    async def _send(self, message) -> None:
        if message["type"] == "http.response.start":
            self.status = message["status"]
        elif message["type"] == "http.response.body":
            self.body += message.get("body", b"")
            if not message.get("more_body"):
                self._done.set()

    async def run(self) -> "AsgiCall":
        path, _, query = self.path.partition("?")
        scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": self.method,
                 "scheme": "http", "path": path, "raw_path": path.encode(), "query_string": query.encode(),
                 "root_path": "", "headers": self.headers, "client": ("127.0.0.1", 50000),
                 "server": ("testserver", 80), "state": {}}
        try:
            await self.app(scope, self._receive, self._send)
        finally:
            self._done.set()
        return self

    def json(self):
        import json

        return json.loads(self.body)
