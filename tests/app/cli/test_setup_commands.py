"""The set-up commands as an operator runs them (issue 17, §5): fresh processes, production settings.

``clinics``, ``users`` and ``tokens`` use no secret key (it signs only the browsers' CSRF tokens), so they run
without ``CHAKAMO_SECRET_KEY``; ``serve`` still refuses to start without one.  A database already at the newest
migration is not handed to alembic (the fast path of :func:`app.cli.admin._database`), and one behind it is
still migrated.  Speed is measured by ``benchmarks/cli_setup.py``, not here.
"""

from __future__ import annotations

import os
import subprocess
import sys


def _chakamo(data_dir, *args: str, stdin: str | None = None, **env_extra: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("CHAKAMO_")} | {
        "CHAKAMO_DATA_DIR": str(data_dir), "CHAKAMO_ENV": "production"} | env_extra
    return subprocess.run([sys.executable, "-m", "app.cli.main", *args], env=env, input=stdin, capture_output=True,
                          text=True, timeout=300)


def test_setup_commands_need_no_secret_key_but_serve_does(tmp_path):
    assert _chakamo(tmp_path, "clinics", "create", "Norte").returncode == 0
    out = _chakamo(tmp_path, "users", "create", "--clinic", "Norte", "--email", "a@norte.org", "--role", "admin",
                   "--password-stdin", stdin="correct horse battery staple\n")
    assert out.returncode == 0, out.stderr
    out = _chakamo(tmp_path, "tokens", "create", "--clinic", "Norte")
    assert out.returncode == 0 and len(out.stdout.strip().splitlines()[-1]) >= 32, out.stderr
    out = _chakamo(tmp_path, "serve", "--port", "1")
    assert out.returncode == 2 and "CHAKAMO_SECRET_KEY" in out.stderr


def test_a_database_behind_the_newest_migration_is_still_migrated(tmp_path):
    from alembic import command
    from sqlalchemy import inspect

    from app.store.database import Database, alembic_config

    assert _chakamo(tmp_path, "clinics", "create", "Norte").returncode == 0
    db = Database(f"sqlite:///{(tmp_path / 'chakamo.db').as_posix()}")
    cfg = alembic_config(db.engine)
    with db.engine.begin() as connection:
        cfg.attributes["connection"] = connection
        command.downgrade(cfg, "0007")
    assert "idempotency_keys" not in inspect(db.engine).get_table_names()
    assert _chakamo(tmp_path, "tokens", "create", "--clinic", "Norte").returncode == 0
    assert "idempotency_keys" in inspect(db.engine).get_table_names()
    db.dispose()
