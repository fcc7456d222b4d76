"""Real servers for the tests that need them, started and stopped by the tests themselves, on loopback.

* :class:`RedisServer` — Debian's ``redis-server`` on a free port in a temporary folder (no persistence
  unless asked: a restart then comes back *empty*, the harder case for "nothing lost");
* :class:`PostgresServer` — a private PostgreSQL cluster (``initdb`` as the ``postgres`` system user, trust
  authentication on 127.0.0.1, a free port), so a test may stop and restart it without disturbing the
  shared server other tests use;
* :class:`ChakamoProcess` — a ``chakamo`` subcommand (``worker``, ``serve``…) as a real subprocess in its own
  process group, so a test can SIGKILL it with all its children, as a crash would.

Each ``start`` waits (bounded) until the service answers; ``stop`` always cleans up.  A missing binary
raises :class:`Missing` (tests turn it into a skip; benchmarks print it).  Used by the tests of the
distributed engine and its faults and by ``benchmarks/load.py``.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

VENV_BIN = Path(sys.executable).parent


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(check, timeout_s: float, what: str, every_s: float = 0.1):
    """Call ``check()`` until it returns a truthy value (returned) or ``timeout_s`` passes (AssertionError)."""
    deadline = time.monotonic() + timeout_s
    last = None
    while time.monotonic() < deadline:
        try:
            value = check()
            if value:
                return value
        except Exception as exc:  # noqa: BLE001 — still starting: try again
            last = exc
        time.sleep(every_s)
    raise AssertionError(f"{what} not reached within {timeout_s:g} s" + (f" (last error: {last!r})" if last else ""))


def _port_open(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex(("127.0.0.1", port)) == 0


class Missing(RuntimeError):
    """A server binary is not installed; the message says which Debian package brings it."""


def require(binary: str) -> str:
    path = shutil.which(binary)
    if path is None:
        raise Missing(f"{binary} not installed (apt-get install {binary})")
    return path


def pg_bin(name: str) -> str:
    found = sorted(Path("/usr/lib/postgresql").glob(f"*/bin/{name}"))
    if not found:
        raise Missing("PostgreSQL server binaries not installed (apt-get install postgresql)")
    return str(found[-1])


class RedisServer:
    """``redis-server`` on a free loopback port; :meth:`stop` / :meth:`start` restart it (empty by default)."""

    def __init__(self, folder: Path, persistent: bool = False) -> None:
        self.binary = require("redis-server")
        self.folder, self.persistent = Path(folder), persistent
        self.folder.mkdir(parents=True, exist_ok=True)
        self.port = free_port()
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.port}/0"

    def start(self) -> "RedisServer":
        args = [self.binary, "--port", str(self.port), "--bind", "127.0.0.1", "--dir", str(self.folder),
                "--save", "", "--appendonly", "yes" if self.persistent else "no", "--protected-mode", "no"]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wait_until(lambda: _port_open(self.port), 10, "redis-server listening")
        return self

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)
        self.proc = None


class PostgresServer:
    """A private PostgreSQL cluster in a new folder (module docstring); ``url`` names its ``postgres`` database."""

    def __init__(self) -> None:
        import tempfile

        self.initdb, self.pg_ctl = pg_bin("initdb"), pg_bin("pg_ctl")
        # not under pytest's tmp_path: its parents are private to root, and the server runs as ``postgres``
        self.folder = Path(tempfile.mkdtemp(prefix="chakamo-pg-"))
        self.folder.chmod(0o755)
        self.data = self.folder / "pgdata"
        self.port = free_port()

    @property
    def url(self) -> str:
        return f"postgresql+psycopg://postgres@127.0.0.1:{self.port}/postgres"

    def _as_postgres(self, *args: str) -> None:
        cmd = list(args)
        if os.geteuid() == 0:  # initdb and postgres refuse to run as root
            cmd = ["su", "postgres", "-s", "/bin/sh", "-c", " ".join(f"'{a}'" for a in args)]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=120)

    def start(self) -> "PostgresServer":
        if not self.data.exists():
            if os.geteuid() == 0:
                shutil.chown(self.folder, "postgres", "postgres")
            self._as_postgres(self.initdb, "-D", str(self.data), "-U", "postgres", "--auth=trust", "-E", "UTF8")
        opts = f"-p {self.port} -k {self.folder} -c listen_addresses=127.0.0.1 -c fsync=off"
        self._as_postgres(self.pg_ctl, "-D", str(self.data), "-o", opts, "-l", str(self.folder / "log"), "-w",
                          "start")
        return self

    def stop(self) -> None:
        if (self.data / "postmaster.pid").exists():
            self._as_postgres(self.pg_ctl, "-D", str(self.data), "-m", "fast", "-w", "stop")

    def remove(self) -> None:
        """Stop the server and delete its cluster."""
        self.stop()
        shutil.rmtree(self.folder, ignore_errors=True)


class ChakamoProcess:
    """``chakamo ARGS`` as a subprocess in its own process group, its output in ``log``."""

    def __init__(self, args: list[str], env: dict[str, str], log: Path) -> None:
        self.args, self.env, self.log = args, env, Path(log)
        self.proc: subprocess.Popen | None = None

    def start(self) -> "ChakamoProcess":
        out = open(self.log, "ab")  # noqa: SIM115 — closed in stop()
        self.proc = subprocess.Popen([str(VENV_BIN / "chakamo"), *self.args], env=self.env, stdout=out,
                                     stderr=subprocess.STDOUT, start_new_session=True)
        self._out = out
        return self

    def kill(self) -> None:
        """SIGKILL the whole process group (a crash: nothing gets to clean up)."""
        if self.proc is not None and self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)

    def stop(self, timeout_s: float = 20.0) -> None:
        """SIGTERM (warm shutdown), then SIGKILL after ``timeout_s``; children left in the group (a Celery
        worker's pool processes) are killed either way."""
        if self.proc is not None and self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.kill()
        if self.proc is not None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        if getattr(self, "_out", None):
            self._out.close()
            self._out = None

    def output(self) -> str:
        return self.log.read_text(errors="replace") if self.log.exists() else ""

    def tail(self, lines: int = 40) -> str:
        """The last ``lines`` lines of its output (for a failure message)."""
        return "\n".join(self.output().splitlines()[-lines:]) or "(no output)"


def chakamo_env(data_dir: Path, **extra: str) -> dict[str, str]:
    """The environment of a ``chakamo`` subprocess: this one's, in development mode, on ``data_dir``."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CHAKAMO_", "DATABASE_URL"))}
    env.update(CHAKAMO_ENV="development", CHAKAMO_DATA_DIR=str(data_dir), PYTHONUNBUFFERED="1", **extra)
    return env


__all__ = ["ChakamoProcess", "Missing", "PostgresServer", "RedisServer", "chakamo_env", "free_port", "pg_bin", "require",
           "wait_until"]
