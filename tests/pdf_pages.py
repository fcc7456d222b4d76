"""The text of each page of a PDF, read by poppler (``pdfinfo`` for the page count, ``pdftotext`` per page), with
runs of white space made one blank: what a reader sees on each page, for tests that look at every page."""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path


def pdf_pages(pdf: bytes) -> list[str]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.pdf"
        path.write_bytes(pdf)
        info = subprocess.run(["pdfinfo", str(path)], check=True, capture_output=True, text=True).stdout
        n = int(next(line.split()[-1] for line in info.splitlines() if line.startswith("Pages:")))
        return [" ".join(subprocess.run(["pdftotext", "-f", str(p), "-l", str(p), "-enc", "UTF-8", str(path), "-"],
                                        check=True, capture_output=True, text=True).stdout.split())
                for p in range(1, n + 1)]
