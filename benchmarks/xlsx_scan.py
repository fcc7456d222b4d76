r"""One .xlsx sheet's data rows found by :func:`app.pipeline.ingestion.xlsx_scan.plain_cells` vs by the regular
expression :data:`app.pipeline.ingestion.xlsx_cells._FAST` (its ``findall`` alone, and with the conversion that
:meth:`~app.pipeline.ingestion.xlsx_cells.Workbook.table` does after it: references and floats by numpy); and the
scan's first step, its tag counts, by :func:`app.pipeline.ingestion.xlsx_scan.occurrences` vs ``bytes.count``.

Usage: ``python -m benchmarks.xlsx_scan [--cycles 10] [--repeats 9]``

The sheet: the largest of the demo's simulated session written in the thesis' xlsx layout
(:func:`app.pipeline.demo.write_session`).  CPU seconds of this process (``time.process_time``), median of
``--repeats``, the three alternated in each repeat, with the load average beside them (the machine is shared).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.xlsx_scan", description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args(argv)

    from app.pipeline.demo import simulate_session, write_session
    from app.pipeline.ingestion.xlsx_cells import _FAST, Workbook
    from app.pipeline.ingestion.xlsx_scan import occurrences, plain_cells, references

    work = Path(tempfile.mkdtemp(prefix="chakamo-xlsx-scan-"))
    try:
        write_session(work / "s", simulate_session(seed=7, side="right", n_cycles=args.cycles), "xlsx")
        path = max((work / "s").glob("*.xlsx"), key=lambda p: p.stat().st_size)
        wb = Workbook(path)
        name = max(wb.sheetnames, key=lambda n: len(wb._sheet_data(n)))
        body = wb._sheet_data(name)
        cut = body.find(b"</row>") + len(b"</row>")   # below the header, as table() scans

        def findall_and_convert() -> None:
            head = np.array(_FAST.findall(body, cut), dtype=bytes).reshape(-1, 3)
            references(head[:, 0])
            head[:, 2].astype(np.float64)

        texts = [b"<", b"<c ", b"<row", b"</row"]
        ways = {"plain_cells": lambda: plain_cells(body, cut), "_FAST.findall": lambda: _FAST.findall(body, cut),
                "findall + conversion": findall_and_convert,
                "its counts (numpy)": lambda: occurrences(body, texts, cut),
                "its counts (bytes)": lambda: [body.count(t, cut) for t in texts]}
        cpus: dict[str, list[float]] = {k: [] for k in ways}
        for _ in range(args.repeats):
            for k, run in ways.items():
                c = time.process_time()
                run()
                cpus[k].append(time.process_time() - c)
        print(f"{path.name} sheet {name!r}: {len(body) / 1e6:.1f} MB, {body.count(b'<c ')} cells; median of "
              f"{args.repeats}, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print(f"{'way':<22} {'CPU s':>7} {'× plain_cells':>14}")
        base = statistics.median(cpus["plain_cells"])
        for k, v in cpus.items():
            print(f"{k:<22} {statistics.median(v):7.3f} {statistics.median(v) / base:14.2f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
