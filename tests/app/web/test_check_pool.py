"""Uploads checked in the server's warm helper process (``app.state.check_pool``, CHAKAMO_RENDER_PROCESSES > 0):
the same answer as a check in the request thread, and a helper that breaks falls back to the thread."""

from __future__ import annotations

from web_helpers import clinic_token, demo_files, make_settings, new_session


def test_uploads_are_checked_in_the_helper_process_with_the_same_answer(tmp_path, demo_dir, caplog):
    import logging

    from fastapi.testclient import TestClient

    from app.web.main import create_app

    caplog.set_level(logging.WARNING)
    answers, after_delete = [], []
    for processes in (1, 0):
        settings = make_settings(tmp_path / f"data{processes}", CHAKAMO_RENDER_PROCESSES=processes)
        with TestClient(create_app(settings)) as client:
            pool = client.app.state.check_pool
            assert (pool is not None) == bool(processes)
            handed = []
            if pool is not None:
                assert pool.wait_warm(120)
                submit = pool.submit
                pool.submit = (lambda fn, *a, handed=handed, submit=submit:  # count hand-overs
                               handed.append(fn.__name__) or submit(fn, *a))
            h = clinic_token(settings, "Pool")
            _, sid = new_session(client, h, "POOL-1")
            r = client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h)
            assert r.status_code == 201, r.text
            answers.append(r.json()["ingestion"])
            if pool is not None:  # it ran there: handed over once, and its answer used (no local fallback)
                assert handed == ["check_ingestion"] and "failed in the helper process" not in caplog.text
                pool.shutdown()  # a broken helper: the next check runs in the request thread, same answer
            first = r.json()["recordings"][0]["id"]
            assert client.delete(f"/api/v1/sessions/{sid}/recordings/{first}", headers=h).status_code == 204
            after_delete.append(client.get(f"/api/v1/sessions/{sid}", headers=h).json()["ingestion"])
            if pool is not None:
                assert handed == ["check_ingestion"] * 2 and "render pool unavailable" in caplog.text  # fell back
    assert answers[0]["ok"] and answers[0] == answers[1]
    assert not after_delete[0]["ok"] and after_delete[0] == after_delete[1]  # a recording missing, said alike
