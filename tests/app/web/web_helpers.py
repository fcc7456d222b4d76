"""Helpers of the web application tests (imported by the tests and by conftest.py)."""

from __future__ import annotations

import time
from pathlib import Path


def make_settings(data_dir: Path, **extra):
    """Development settings on ``data_dir``, one job thread, no render process unless ``extra`` asks."""
    from app.settings import Settings

    values = {"CHAKAMO_ENV": "development", "CHAKAMO_DATA_DIR": data_dir, "CHAKAMO_WORKERS": 1,
              "CHAKAMO_RENDER_PROCESSES": 0} | extra
    return Settings(**values)


def clinic_token(settings, name: str, role: str = "clinician") -> dict[str, str]:
    """Create clinic ``name`` (if new) and a token through the CLI functions; return the bearer header."""
    from app import admin_cli

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
