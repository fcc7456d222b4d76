"""``chakamo reprocess`` asks again for the choices a session was processed with (:mod:`app.jobs.reprocess`, real
database and pipeline): heading, side, calibration and angle convention are carried over from the job behind the
session's current analysis, so ``--force`` does not silently reset them to the defaults, and an analysis counts as
current only for the same choices (:func:`app.jobs.queue.current_analysis`)."""

from __future__ import annotations

import datetime as dt

from web_helpers import clinic_token, demo_files, new_session, wait_job

CHOSEN = {"heading": "magnetometer", "side": "right", "calibration": "functional"}
BODY = {"filter": "guo", "lang": "en", **CHOSEN}


def test_reprocess_carries_the_sessions_choices(client, settings, demo_dir):
    from app.jobs.queue import current_analysis
    from app.jobs.reprocess import reprocess
    from app.store.database import Database
    from app.store.models import Job, KneeSession

    h = clinic_token(settings, "Choices")
    _, sid = new_session(client, h, "CH-1")
    assert client.post(f"/api/v1/sessions/{sid}/recordings", files=demo_files(demo_dir), headers=h).status_code == 201
    first = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json=BODY,
                                         headers=h).json()["job_id"], h)
    assert first["status"] == "done", first
    # a later run with the thesis' angles, only to compare: not the session's current analysis
    zyx = wait_job(client, client.post(f"/api/v1/sessions/{sid}/process", json={
        **BODY, "angle_convention": "thesis_zyx"}, headers=h).json()["job_id"], h)
    assert zyx["status"] == "done", zyx
    since = dt.date.today() - dt.timedelta(days=1)

    outcomes, _ = reprocess(settings, filter_name="guo", since=since, lang="en")
    assert [o.status for o in outcomes] == ["current"], outcomes  # the first run's choices: already done
    forced, _ = reprocess(settings, filter_name="guo", since=since, lang="en", force=True)
    assert [o.status for o in forced] == ["queued"], forced
    db = Database(settings.db_url)
    try:
        with db.session() as s:
            job = s.get(Job, forced[0].job_id)
            assert {k: getattr(job, k) for k in ("heading", "side", "calibration", "angle_method")} == \
                {**CHOSEN, "angle_method": "grood_suntay"}
            session = s.get(KneeSession, sid)
            # current for the choices asked, not for others
            assert current_analysis(s, session, "guo", "en", **CHOSEN) == first["analysis_id"]
            assert current_analysis(s, session, "guo", "en") is None  # the defaults: static, auto
            assert current_analysis(s, session, "guo", "en", **CHOSEN, angle_method="thesis_zyx") == zyx["analysis_id"]
    finally:
        db.dispose()
