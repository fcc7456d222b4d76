"""The deployment :mod:`benchmarks.load` measures, started from nothing and always torn down.

``celery`` backend (the scaled-out deployment, as ``docker/compose.yaml`` runs it, natively):

* a private PostgreSQL cluster (:class:`benchmarks.live_services.PostgresServer`, its ``postgres`` database)
  and ``redis-server`` (:class:`~benchmarks.live_services.RedisServer`) on free loopback ports;
* ``chakamo migrate`` once, then a clinic and a clinician API token (:func:`app.cli.admin.create_clinic`,
  :func:`~app.cli.admin.create_token`, on the same ``DATABASE_URL``);
* ``chakamo serve`` (the API, one uvicorn process) and ``workers`` separate ``chakamo worker --concurrency 1``
  processes — "2 workers" is two Celery worker processes running one job each, the shape of two worker
  containers; each is waited for until Celery logs that it is ready, so start-up is not measured as
  throughput.

``inprocess`` backend (the embedded default): SQLite under the data dir, ``chakamo serve`` alone with
``CHAKAMO_WORKERS=workers`` job threads inside it.

Everything is a real subprocess on 127.0.0.1 (:class:`~benchmarks.live_services.ChakamoProcess`, its own
process group); the logs stay in the temporary folder and their tails are printed when a start fails.  On
exit, whatever happened: workers get SIGTERM (SIGKILL after 10 s), then the API, Redis and PostgreSQL stop
and the PostgreSQL cluster's folder is removed; the caller removes ``root``.
"""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path

from benchmarks.live_services import (VENV_BIN, ChakamoProcess, Missing, PostgresServer, RedisServer, chakamo_env,
                                      free_port, wait_until)

#: bounded waits of the start-up (the machine is shared: generous)
START_TIMEOUT_S = 120.0
#: the clinic the benchmark's clinicians belong to
CLINIC = "Load benchmark clinic"


@dataclass
class Stack:
    """A running deployment: the API's ``base_url``, a clinician's bearer ``headers`` and the processes."""

    backend: str
    base_url: str
    headers: dict[str, str]
    api: ChakamoProcess
    workers: list[ChakamoProcess]
    describe: str  # one line: what runs


def failure_excerpt(stack: Stack, tail: int = 14) -> str:
    """Per process log: how often each exception was logged and the end of the last traceback (the logs are
    deleted with the temporary folder, so a failed run must show them)."""
    from collections import Counter

    out = []
    for proc in [stack.api, *stack.workers]:
        text = proc.output().splitlines()
        errors: Counter[str] = Counter()
        last: list[str] = []
        for i, line in enumerate(text):
            if line.startswith("Traceback"):
                end = next((j for j in range(i + 1, len(text)) if text[j] and not text[j].startswith(" ")), i)
                errors[text[end][:200]] += 1
                last = text[max(i, end - tail):end + 1]
        out.append(f"--- {proc.args[0]} ({proc.log.name}): "
                   + ("; ".join(f"{n} × {e}" for e, n in errors.most_common(5)) or "no traceback"))
        out.extend(last)
    return "\n".join(out)


def _api_ready(base_url: str) -> bool:
    import httpx

    return httpx.get(base_url + "/readyz", timeout=2).status_code == 200


@contextmanager
def running_stack(root: Path, backend: str, workers: int) -> Iterator[Stack]:
    """Start the deployment of ``backend`` with ``workers`` workers under ``root`` (module docstring)."""
    from app.cli import admin as admin_cli
    from app.settings import Settings

    if not (VENV_BIN / "chakamo").exists():
        raise Missing(f"{VENV_BIN / 'chakamo'} not found; install the project (pip install -e .) in this venv")
    data = root / "data"
    extra = {"CHAKAMO_JOB_BACKEND": backend, "CHAKAMO_WORKERS": str(workers)}
    with ExitStack() as stack:
        if backend == "celery":
            pg = PostgresServer()
            stack.callback(pg.remove)
            pg.start()
            redis = RedisServer(root / "redis")
            stack.callback(redis.stop)
            redis.start()
            extra |= {"DATABASE_URL": pg.url, "CHAKAMO_BROKER_URL": redis.url}
        env = chakamo_env(data, **extra)
        done = subprocess.run([str(VENV_BIN / "chakamo"), "migrate"], env=env, capture_output=True, text=True,
                              timeout=START_TIMEOUT_S)
        if done.returncode != 0:
            raise RuntimeError(f"chakamo migrate failed (status {done.returncode}): {done.stderr[-800:]}")
        settings = Settings(**{k: v for k, v in env.items() if k.startswith(("CHAKAMO_", "DATABASE_URL"))})
        admin_cli.create_clinic(settings, CLINIC)
        token = admin_cli.create_token(settings, clinic=CLINIC, label="load benchmark")

        port = free_port()
        api = ChakamoProcess(["serve", "--host", "127.0.0.1", "--port", str(port)], env, root / "serve.log")
        stack.callback(api.stop)
        api.start()
        base_url = f"http://127.0.0.1:{port}"
        try:
            wait_until(lambda: api.proc.poll() is None and _api_ready(base_url), START_TIMEOUT_S,
                       "chakamo serve answering /readyz with 200", every_s=0.25)
        except AssertionError as exc:
            raise RuntimeError(f"{exc}; its log ends with:\n{api.tail(15)}") from None

        procs: list[ChakamoProcess] = []
        if backend == "celery":
            for i in range(workers):
                w = ChakamoProcess(["worker", "--concurrency", "1"], env, root / f"worker-{i}.log")
                stack.callback(w.stop, 10.0)
                procs.append(w.start())
            for i, w in enumerate(procs):
                try:
                    wait_until(lambda w=w: w.proc.poll() is None and " ready." in w.output(), START_TIMEOUT_S,
                               f"chakamo worker {i} ready", every_s=0.25)
                except AssertionError as exc:
                    raise RuntimeError(f"{exc}; its log ends with:\n{w.tail(15)}") from None
            describe = (f"API: chakamo serve (1 uvicorn process); jobs: {workers} chakamo worker processes "
                        f"(Celery prefork, --concurrency 1 each); PostgreSQL {pg.port}, Redis {redis.port}")
        else:
            describe = f"API: chakamo serve with {workers} in-process job threads; SQLite"
        yield Stack(backend, base_url, {"Authorization": f"Bearer {token}"}, api, procs, describe)


__all__ = ["CLINIC", "Stack", "failure_excerpt", "running_stack"]
