"""Running the compose file's chakamo commands natively: the environment adapted to loopback, the processes
started in their own process groups and always stopped.

What changes between a container and this machine, and nothing else: the ``postgres`` and ``redis`` host
names become the test's own database and redis-server, the image's ``/data`` becomes a temporary folder,
``chakamo`` is this virtualenv's console script, and ``serve`` listens on a free loopback port instead of
``0.0.0.0:8000``.  The commands and the variables themselves are read from compose.yaml and the Dockerfile.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path, PurePosixPath
from urllib.parse import urlsplit, urlunsplit

from benchmarks.live_services import ChakamoProcess, free_port
from deploy_files import interpolate


def chakamo_argv(command: list[str]) -> list[str]:
    """``command`` (``["chakamo", ...]``) with ``chakamo`` resolved to this interpreter's installation."""
    if command[0] != "chakamo":
        raise ValueError(f"not a chakamo command: {command}")
    script = Path(sys.executable).with_name("chakamo")
    head = [str(script)] if script.is_file() else [sys.executable, "-m", "app.cli.main"]
    return head + command[1:]


def with_option(command: list[str], option: str, value: str) -> list[str]:
    """``command`` with the value after ``option`` replaced (the option must be there)."""
    if option not in command:
        raise ValueError(f"{command} has no {option}")
    i = command.index(option)
    return command[: i + 1] + [value] + command[i + 2:]


def _replace_host(url: str, expected_host: str, target: str) -> str:
    """``url`` pointed at ``target`` (a full URL), after checking it names the compose service it should."""
    host = urlsplit(url).hostname
    if host != expected_host:
        raise ValueError(f"{url!r} does not point at the compose service {expected_host!r}")
    return target


def loopback_environment(image_env: dict[str, str], compose_env: dict[str, str], secrets: dict[str, str], *,
                         database_url: str, broker_url: str, data_dir: Path) -> dict[str, str]:
    """The environment a chakamo container gets (the image's ``ENV``, then the service's ``environment``
    interpolated with ``secrets``), adapted to this machine (see the module docstring)."""
    merged = {k: v for k, v in image_env.items() if k != "PATH"}
    merged |= {k: interpolate(v, secrets) for k, v in compose_env.items()}
    container_data = PurePosixPath(merged["CHAKAMO_DATA_DIR"])
    adapted = {}
    for key, value in merged.items():
        path = PurePosixPath(value)
        if value.startswith("/") and (path == container_data or container_data in path.parents):
            value = str(data_dir / path.relative_to(container_data))
        adapted[key] = value
    adapted["DATABASE_URL"] = _replace_host(adapted["DATABASE_URL"], "postgres", database_url)
    broker = urlsplit(adapted["CHAKAMO_BROKER_URL"])
    target = urlsplit(broker_url)
    adapted["CHAKAMO_BROKER_URL"] = _replace_host(
        adapted["CHAKAMO_BROKER_URL"], "redis", urlunsplit(broker._replace(netloc=target.netloc)))
    base = {k: v for k, v in os.environ.items()
            if not (k.startswith(("CHAKAMO_", "NUMBA_", "MPL", "XDG_")) or k == "DATABASE_URL")}
    base["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
    return base | adapted


def chakamo_process(command: list[str], env: dict[str, str], log_path: Path) -> ChakamoProcess:
    """A compose service's ``command`` (``["chakamo", ...]``) started as a real process of this machine."""
    if command[0] != "chakamo":
        raise ValueError(f"not a chakamo command: {command}")
    return ChakamoProcess(command[1:], env, log_path).start()


def http_status(url: str) -> int | None:
    """The status ``GET url`` answers, or None when nothing answers."""
    try:
        with urllib.request.urlopen(url, timeout=5) as response:
            return response.status
    except urllib.error.HTTPError as exc:
        return exc.code
    except (urllib.error.URLError, OSError):
        return None


def wait_for_status(url: str, procs: dict[str, ChakamoProcess], *, timeout_s: float = 180.0) -> int:
    """Poll ``url`` until it answers at all; fail early with its log when one of ``procs`` exits."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for name, p in procs.items():
            if p.proc.poll() is not None:
                raise AssertionError(f"{name} exited with status {p.proc.returncode}:\n{p.tail()}")
        status = http_status(url)
        if status is not None:
            return status
        time.sleep(0.5)
    raise AssertionError(f"{url} did not answer within {timeout_s:.0f} s")


def run_healthcheck(command: list[str], port: int) -> int:
    """Run the image's health check (a ``python -c`` program asking 127.0.0.1:8000) against ``port``."""
    if command[:2] != ["python", "-c"]:
        raise ValueError(f"the health check is not a `python -c` program: {command}")
    program = command[2].replace("127.0.0.1:8000", f"127.0.0.1:{port}")
    if program == command[2]:
        raise ValueError("the health check does not ask 127.0.0.1:8000")
    return subprocess.run([sys.executable, "-c", program], capture_output=True, timeout=60).returncode


__all__ = ["chakamo_argv", "chakamo_process", "free_port", "http_status", "loopback_environment", "run_healthcheck",
           "wait_for_status", "with_option"]
