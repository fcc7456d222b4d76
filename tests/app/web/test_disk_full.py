"""A full disk while a job stores its artefacts: the job fails cleanly with a sentence, nothing half-written
is left or recorded, the uploads stay intact, and processing again works once there is space.

The blob store lives on a real, small ``tmpfs`` (mounted by the test: root only; skipped elsewhere, failed in
CI), sized after the upload to the uploads plus 1 MB, so the kernel itself answers ``ENOSPC`` while the reports
are stored; then it is grown in place (``mount -o remount,size=…``), as an administrator freeing space would.
Reports stored before the disk filled stay as files no row names (content-addressed: deleting them could race
with another job storing the same content); they are not recorded, and are reused by the next run.
"""

from __future__ import annotations

import os
import subprocess

import pytest

from web_helpers import clinic_token, demo_files, make_settings, new_session, wait_job


def _mount(args: list[str]) -> None:
    subprocess.run(["mount", *args], check=True, capture_output=True, timeout=30)


@pytest.fixture
def small_blob_disk(tmp_path):
    """``data/blobs`` on a tmpfs of the uploads' size plus 1 MB; unmounted afterwards."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    blobs = tmp_path / "data" / "blobs"
    blobs.mkdir(parents=True)
    try:
        _mount(["-t", "tmpfs", "-o", "size=6m", "tmpfs", str(blobs)])
    except (subprocess.CalledProcessError, FileNotFoundError) as exc:
        if os.environ.get("CI"):  # CI runs as root on our machines: a skip there would hide the fault test
            pytest.fail(f"cannot mount a tmpfs in CI ({exc})")
        pytest.skip(f"cannot mount a tmpfs here ({exc})")
    try:
        yield blobs
    finally:
        subprocess.run(["umount", "-l", str(blobs)], capture_output=True, timeout=30)


def _blobs(folder) -> set[str]:
    """The content addresses stored under ``folder`` (``aa/bbbb…`` → ``aabbbb…``), temporary files left out."""
    return {p.parent.name + p.name for p in folder.glob("??/*") if p.is_file()}


def test_a_full_disk_fails_the_job_cleanly_and_processing_again_works(tmp_path, small_blob_disk, demo_dir):
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    upload_bytes = sum(len(f[1][1]) for f in demo_files(demo_dir))
    assert upload_bytes < 5 * 2**20  # the tmpfs takes the uploads, not the reports as well
    settings = make_settings(tmp_path / "data")
    with TestClient(create_app(settings)) as client:
        h = clinic_token(settings, "Clinica Llena")
        _, session_id = new_session(client, h, "DISK-1")
        r = client.post(f"/api/v1/sessions/{session_id}/recordings", files=demo_files(demo_dir), headers=h)
        assert r.status_code == 201 and r.json()["ingestion"]["ok"], r.text
        _mount(["-o", f"remount,size={upload_bytes + 2**20}", str(small_blob_disk)])  # ~1 MB left
        uploads = _blobs(small_blob_disk)
        assert len(uploads) == len(demo_files(demo_dir))

        job = wait_job(client, client.post(f"/api/v1/sessions/{session_id}/process", json={}, headers=h)
                       .json()["job_id"], h)
        assert job["status"] == "failed", job
        assert "disk is full" in job["error"] and "process the session again" in job["error"], job["error"]
        assert client.get(f"/api/v1/sessions/{session_id}/results", headers=h).status_code == 404
        assert list((small_blob_disk / ".incoming").iterdir()) == []  # no partial file left behind
        assert uploads <= _blobs(small_blob_disk)  # every upload still stored

        _mount(["-o", "remount,size=64m", str(small_blob_disk)])  # the administrator frees space
        job = wait_job(client, client.post(f"/api/v1/sessions/{session_id}/process", json={}, headers=h)
                       .json()["job_id"], h)
        assert job["status"] == "done", job
        assert client.get(f"/api/v1/sessions/{session_id}/report.pdf?lang=en", headers=h).content.startswith(b"%PDF")
        assert len(client.get(f"/api/v1/sessions/{session_id}", headers=h).json()["recordings"]) == \
            len(demo_files(demo_dir))


def test_an_upload_onto_a_full_disk_answers_507_with_the_jobs_sentence(tmp_path, small_blob_disk):
    """Issue 16, finding 10g: the kernel's ENOSPC while an upload is written is a 507 saying the disk is full
    (the job path's sentence, in es/en/pt), not a bare 500; nothing of it is stored, and once space is freed
    the same upload is taken."""
    from fastapi.testclient import TestClient

    from app.web.main import create_app

    settings = make_settings(tmp_path / "data")
    big = b"time,acc_x\n" + b"0.000,1.000\n" * (8 * 2**20 // 12)  # 8 MB on a 6 MB disk
    with TestClient(create_app(settings)) as client:
        h = clinic_token(settings, "Clinica Llena")
        _, session_id = new_session(client, h, "DISK-2")
        url = f"/api/v1/sessions/{session_id}/recordings"
        r = client.post(url, files=[("files", ("big.csv", big, "text/csv"))], headers=h)
        assert r.status_code == 507, r.text
        body = r.json()
        assert body["code"] == "request.disk_full" and "disk is full" in body["detail"]
        assert "upload them again" in body["detail"] and set(body["message"]) == {"es", "en", "pt"}
        assert list((small_blob_disk / ".incoming").iterdir()) == []  # no partial file left behind
        assert client.get(f"/api/v1/sessions/{session_id}", headers=h).json()["n_recordings"] == 0

        _mount(["-o", "remount,size=64m", str(small_blob_disk)])  # the administrator frees space
        assert client.post(url, files=[("files", ("big.csv", big, "text/csv"))], headers=h).status_code == 201
