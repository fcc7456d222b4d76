"""One clinic, one patient and two empty sessions in a migrated database with a blob store: the world the
erasure tests (tests/app/store/test_erasure*.py) start from; and :func:`wait_for`, the store tests' bounded wait for
another thread to reach a state."""

from __future__ import annotations

import time
from contextlib import contextmanager
from pathlib import Path


def wait_for(condition, what: str, timeout_s: float = 30.0) -> None:
    """Poll ``condition()`` until it holds; fail with ``what`` after ``timeout_s``."""
    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, what
        time.sleep(0.005)


@contextmanager
def erasure_world(url: str, tmp_path: Path, clinic_name: str, external_id: str):
    from app.store.blobs import BlobStore
    from app.store.database import Database
    from app.store.models import Clinic
    from app.store.patients import add_patient
    from app.store.sessions import add_session

    db = Database(url)
    db.migrate()
    store = BlobStore(tmp_path / "blobs")
    with db.session() as s:
        clinic = Clinic(name=clinic_name)
        s.add(clinic)
        s.flush()
        pid = add_patient(s, clinic.id, {"external_id": external_id, "side": "right"}).id
        sids = [add_session(s, clinic.id, pid, {}).id for _ in range(2)]
        cid = clinic.id
    try:
        yield {"db": db, "store": store, "cid": cid, "pid": pid, "sids": sids}
    finally:
        db.dispose()
