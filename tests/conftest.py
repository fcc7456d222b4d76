"""Fixtures shared across the test tree.

``pg_url``: a new empty database on the PostgreSQL server named by ``CHAKAMO_TEST_POSTGRES_URL`` (which
``.ci/run`` starts and sets), dropped after the test; skipped when the variable is unset.

``browser``: a real headless Chromium (Debian's ``/usr/bin/chromium``, installed by ``.ci/run``) driven by
Playwright.  Playwright's own browser download cannot work on our machines (no network but the package
registries), so it launches the system binary.  Tests that use it skip when either is missing.

Parallel runs (pytest-xdist, ``-n auto`` in pyproject.toml): each worker gets its own temporary folders
(``tmp_path``), databases (unique names), servers (kernel-chosen ports) and browser profile.  The numba cache
is the one thing the workers would otherwise share in the source tree (``__pycache__/*.nbi|nbc``): numba writes
each file atomically, but a function's index is read, extended and written back without a lock, so two workers
compiling two signatures of one function at once can leave an index that names the other's machine code.  So
each worker compiles into a private ``NUMBA_CACHE_DIR`` seeded with a copy of the tree's cache, and when the
run ends the controller copies back the functions the tree did not have yet (one process, so no race).  A
``NUMBA_CACHE_DIR`` set by the caller is left alone.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: the packages whose ``@njit(cache=True)`` functions fill the numba cache
NUMBA_PACKAGES = ("estimators", "app", "reports")
_NUMBA_BASE = "CHAKAMO_TEST_NUMBA_BASE"     # the controller's folder of the workers' caches


def _cache_subdir(source_dir: Path) -> str:
    """The folder numba uses under ``NUMBA_CACHE_DIR`` for the modules of ``source_dir``."""
    from numba.core.caching import UserProvidedCacheLocator

    return UserProvidedCacheLocator.get_suitable_cache_subpath(str(source_dir / "module.py"))


def _tree_caches() -> dict[str, Path]:
    """{subfolder under NUMBA_CACHE_DIR: the tree's ``__pycache__``} for every package folder of the project."""
    out = {}
    for package in NUMBA_PACKAGES:
        for folder in [REPO / package, *(REPO / package).rglob("*")]:
            if folder.is_dir() and folder.name != "__pycache__" and (folder / "__init__.py").exists():
                out[_cache_subdir(folder)] = folder / "__pycache__"
    return out


def _copy_cache_files(src: Path, dst: Path, only_new: bool) -> None:
    """Copy every function's index (``.nbi``) with its machine code (``.nbc``) from ``src`` to ``dst``; the code
    first and the index last, each through a temporary name and a rename, so a reader never sees a half file.
    ``only_new``: skip the functions ``dst`` already has."""
    for index in sorted(src.glob("*.nbi")):
        if only_new and (dst / index.name).exists():
            continue
        dst.mkdir(parents=True, exist_ok=True)
        stem = index.name[: -len(".nbi")]
        for path in [*sorted(src.glob(f"{stem}.*.nbc")), index]:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=dst)
            os.close(fd)
            shutil.copyfile(path, tmp)
            os.replace(tmp, dst / path.name)


def _private_numba_cache(worker: str) -> None:
    """Point numba at this worker's own cache folder, seeded from the tree (module docstring)."""
    base = os.environ.get(_NUMBA_BASE)
    if not base or os.environ.get("NUMBA_CACHE_DIR"):
        return
    mine = Path(base) / worker
    for sub, pycache in _tree_caches().items():
        if pycache.is_dir():
            _copy_cache_files(pycache, mine / sub, only_new=False)
    os.environ["NUMBA_CACHE_DIR"] = str(mine)   # read when numba is imported: no project module is imported yet


if os.environ.get("PYTEST_XDIST_WORKER"):
    _private_numba_cache(os.environ["PYTEST_XDIST_WORKER"])


def pytest_configure(config):
    """The controller of a parallel run makes the folder of its workers' numba caches (they inherit it)."""
    parallel = getattr(config.option, "numprocesses", None) and not os.environ.get("PYTEST_XDIST_WORKER")
    if parallel and not os.environ.get("NUMBA_CACHE_DIR") and _NUMBA_BASE not in os.environ:
        os.environ[_NUMBA_BASE] = tempfile.mkdtemp(prefix="chakamo-numba-")
        config._chakamo_numba_base = Path(os.environ[_NUMBA_BASE])


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """After the workers have stopped: the functions they compiled that the tree lacks go back to the tree (a
    later run, serial or parallel, loads them instead of compiling again); then their folders are removed."""
    base = getattr(config, "_chakamo_numba_base", None)
    if base is None:
        return
    try:
        tree = _tree_caches()
        for worker in sorted(p for p in base.iterdir() if p.is_dir()):
            for sub in sorted(p for p in worker.iterdir() if p.is_dir()):
                if sub.name in tree:
                    try:
                        _copy_cache_files(sub, tree[sub.name], only_new=True)
                    except OSError:         # a read-only tree: numba would not have written there either
                        pass
    finally:
        shutil.rmtree(base, ignore_errors=True)
        os.environ.pop(_NUMBA_BASE, None)

#: Chromium flags for a closed network: without the background-networking ones Chromium keeps trying to
#: reach Google's hosts; SwiftShader gives WebGL in software (no GPU here).
CHROMIUM_ARGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-extensions", "--hide-scrollbars", "--enable-unsafe-swiftshader")


@pytest.fixture(scope="session")
def browser():
    """A Playwright ``Browser`` on the system Chromium, shared by the whole run."""
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("chromium not installed (apt-get install chromium)")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium, headless=True, args=list(CHROMIUM_ARGS))
        try:
            yield browser
        finally:
            browser.close()


@pytest.fixture
def pg_url():
    """URL of a new empty PostgreSQL database (``CHAKAMO_TEST_POSTGRES_URL``'s server; dropped after the test)."""
    import os

    from live_fixtures import fresh_database

    server = os.environ.get("CHAKAMO_TEST_POSTGRES_URL")
    if not server:
        pytest.skip("CHAKAMO_TEST_POSTGRES_URL not set (no PostgreSQL server)")
    with fresh_database(server) as url:
        yield url
