"""The house's arrows (README "Layout"): the import-linter contracts of pyproject.toml hold.

``app -> reports -> estimators`` and, inside ``app``, ``cli -> web | research -> jobs -> store -> pipeline ->
choices | settings``; nothing outside ``app.web`` imports a router.  ``lint-imports`` reads the imports of every
module statically (nothing is run), so a new arrow pointing the wrong way fails here with the line that drew it.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_the_import_contracts_hold():
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or shutil.which("lint-imports")
    if exe is None:
        pytest.fail("lint-imports is missing: install the test extra (pip install -e '.[test]')")
    run = subprocess.run([exe, "--config", str(REPO / "pyproject.toml"), "--no-cache"], cwd=REPO,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert "3 kept, 0 broken" in run.stdout, run.stdout[-2000:]
