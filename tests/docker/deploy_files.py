"""Readers of the deployment files (``docker/compose.yaml``, ``docker/Dockerfile``, ``.dockerignore``) for the
static checks and the native run.

No Docker engine runs on our machines, so the tests read the files the way the engine would, as far as the
checks need: compose's ``${VAR}`` interpolation (with ``:-`` defaults and ``:?`` required-variable errors),
and the Dockerfile's instructions per build stage (line continuations, comments, ``ENV k=v`` pairs, exec-form
JSON arguments).  Deliberately small: anything these readers do not understand raises, so a construct the
checks cannot see into fails a test instead of passing unread.
"""

from __future__ import annotations

import json
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOCKER_DIR = REPO / "docker"
COMPOSE_FILE = DOCKER_DIR / "compose.yaml"
DOCKERFILE = DOCKER_DIR / "Dockerfile"
DOCKERIGNORE = REPO / ".dockerignore"

#: the services that run the chakamo image (their ``command`` is a chakamo command line)
CHAKAMO_SERVICES = ("migrate", "api", "worker")
#: test values for the compose file's required secrets (never real ones)
TEST_SECRETS = {"POSTGRES_PASSWORD": "pw-for-tests-only", "CHAKAMO_SECRET_KEY": "k" * 48}

_VAR = re.compile(r"\$\$|\$\{(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?:(?P<op>:?[-?])(?P<arg>[^}]*))?\}"
                  r"|\$(?P<bare>[A-Za-z_][A-Za-z0-9_]*)")


class InterpolationError(ValueError):
    """A ``${VAR:?message}`` variable is unset or empty: compose stops with ``message``."""


def load_compose() -> dict:
    """``docker/compose.yaml`` parsed (YAML anchors and ``<<`` merge keys resolved by PyYAML)."""
    import yaml

    return yaml.safe_load(COMPOSE_FILE.read_text(encoding="utf-8"))


def interpolate(value: str, variables: dict[str, str]) -> str:
    """``value`` with compose's variable syntax replaced from ``variables`` (compose's rules: ``:-``/``:?``
    treat an empty value as unset, ``-``/``?`` only an unset one; ``$$`` is a literal ``$``)."""

    def one(match: re.Match) -> str:
        if match.group(0) == "$$":
            return "$"
        name = match.group("name") or match.group("bare")
        op, arg = match.group("op"), match.group("arg") or ""
        current = variables.get(name)
        missing = current is None or (current == "" and op is not None and op.startswith(":"))
        if op is None:
            return current or ""
        if op.endswith("-"):
            return arg if missing else current
        if missing:
            raise InterpolationError(f"{name}: {arg}")
        return current

    return _VAR.sub(one, value)


def variables_used(value: str) -> list[tuple[str, str | None]]:
    """The variables ``value`` interpolates, each with its operator (``:?``, ``:-``, ... or None)."""
    return [(m.group("name") or m.group("bare"), m.group("op")) for m in _VAR.finditer(value) if m.group(0) != "$$"]


def service_environment(service: dict) -> dict[str, str]:
    """A service's ``environment`` as a dict (compose allows a mapping or a list of ``KEY=VALUE``)."""
    env = service.get("environment") or {}
    if isinstance(env, list):
        pairs = [item.split("=", 1) for item in env]
        if any(len(p) != 2 for p in pairs):
            raise ValueError(f"environment entries without '=' are not understood here: {env}")
        env = dict(pairs)
    return {str(k): "" if v is None else str(v) for k, v in env.items()}


def volume_mounts(service: dict) -> dict[str, str]:
    """A service's named-volume mounts, target -> volume name (short syntax ``name:/target[:mode]``)."""
    mounts = {}
    for item in service.get("volumes") or []:
        if isinstance(item, dict):
            mounts[item["target"]] = item.get("source", "")
        else:
            source, target = str(item).split(":")[:2]
            mounts[target] = source
    return mounts


@dataclass
class Stage:
    """One ``FROM`` ... stage of a Dockerfile: its base, its name and its instructions in order."""

    base: str
    name: str | None
    instructions: list[tuple[str, str]] = field(default_factory=list)

    def all(self, keyword: str) -> list[str]:
        return [args for kw, args in self.instructions if kw == keyword]

    def env(self) -> dict[str, str]:
        """The stage's ``ENV`` variables (``ENV k=v k2="v 2"`` form; the legacy ``ENV k v`` form too)."""
        result: dict[str, str] = {}
        for args in self.all("ENV"):
            words = shlex.split(args)
            if words and "=" not in words[0]:
                result[words[0]] = args.split(None, 1)[1] if len(words) > 1 else ""
                continue
            for word in words:
                key, sep, val = word.partition("=")
                if not sep:
                    raise ValueError(f"ENV word {word!r} is not KEY=VALUE")
                result[key] = val
        return result


@dataclass
class Dockerfile:
    args: dict[str, str]     # ARG defaults declared before the first FROM
    stages: list[Stage]

    def resolve(self, text: str) -> str:
        """``text`` with the global ``ARG`` defaults substituted (as ``FROM ${PYTHON_IMAGE}`` uses them)."""
        return interpolate(text, self.args)

    @property
    def final(self) -> Stage:
        return self.stages[-1]


def _logical_lines(text: str) -> list[str]:
    """Instructions joined across ``\\`` continuations, comment and blank lines dropped."""
    lines, current = [], ""
    for raw in text.splitlines():
        stripped = raw.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if stripped.endswith("\\"):
            current += stripped[:-1] + " "
            continue
        lines.append(current + stripped)
        current = ""
    if current:
        raise ValueError("the Dockerfile ends inside a line continuation")
    return lines


def load_dockerfile(path: Path = DOCKERFILE) -> Dockerfile:
    """``docker/Dockerfile`` split into its global ARGs and its stages."""
    args: dict[str, str] = {}
    stages: list[Stage] = []
    for line in _logical_lines(path.read_text(encoding="utf-8")):
        keyword, _, rest = line.partition(" ")
        keyword, rest = keyword.upper(), rest.strip()
        if keyword == "FROM":
            words = rest.split()
            name = words[2] if len(words) == 3 and words[1].upper() == "AS" else None
            if len(words) not in (1, 3):
                raise ValueError(f"FROM {rest!r} is not 'image [AS name]'")
            stages.append(Stage(base=words[0], name=name))
        elif not stages:
            if keyword != "ARG":
                raise ValueError(f"{keyword} before the first FROM")
            key, _, default = rest.partition("=")
            args[key] = default
        else:
            stages[-1].instructions.append((keyword, rest))
    return Dockerfile(args=args, stages=stages)


def exec_form(args: str) -> list[str]:
    """The JSON array of an exec-form ``CMD``/``HEALTHCHECK CMD`` (a shell-form one raises)."""
    value = json.loads(args)
    if not (isinstance(value, list) and all(isinstance(v, str) for v in value)):
        raise ValueError(f"not an exec-form JSON array of strings: {args!r}")
    return value


def healthcheck_command(args: str) -> list[str]:
    """The command of ``HEALTHCHECK [--options] CMD [...]`` (exec form)."""
    head, sep, command = args.partition("CMD ")
    if not sep:
        raise ValueError(f"HEALTHCHECK without CMD: {args!r}")
    return exec_form(command)


def dockerignore_patterns() -> list[str]:
    return [line.strip() for line in DOCKERIGNORE.read_text(encoding="utf-8").splitlines()
            if line.strip() and not line.strip().startswith("#")]


__all__ = ["CHAKAMO_SERVICES", "TEST_SECRETS", "COMPOSE_FILE", "DOCKERFILE", "DOCKERIGNORE", "DOCKER_DIR", "REPO", "Dockerfile",
           "InterpolationError", "Stage", "dockerignore_patterns", "exec_form", "healthcheck_command",
           "interpolate", "load_compose", "load_dockerfile", "service_environment", "variables_used",
           "volume_mounts"]
