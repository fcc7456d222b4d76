r"""Are two ``chakamo process`` output folders the same?  The check behind every speed change that must not
change a number (issue 12 §6: the cold start).

Usage
-----
``python -m benchmarks.same_outputs OLD_DIR NEW_DIR``
    compare two output folders;
``python -m benchmarks.same_outputs --session DIR --old-tree PATH [--new-tree PATH] [-- extra process args]``
    run ``chakamo process`` on the same session from two checkouts (each a fresh interpreter with ``PYTHONPATH``
    set to its tree; ``--new-tree`` defaults to the current directory), then compare.

Each file of either folder gets one verdict:

* ``identical`` — the same bytes (the outputs are reproducible: the workbooks' and the PDF's time stamps are
  fixed, so a change that does not change any number leaves every byte alone);
* otherwise the content is compared, so that a difference in packaging is told from one in numbers:
  ``results.json`` parsed (every value, floats exactly), ``timeseries.npz`` array by array (exactly, NaN equal
  to NaN), the workbooks cell by cell on every sheet (openpyxl, values exactly); the PDF, HTML and scene only as
  bytes.  A verdict ``same content`` or ``DIFFERENT (...)`` then names what differs.

The exit status is 0 when every file is identical or has the same content, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ENTRY = "from app.cli import console; console()"


def _json_diff(a, b, path: str = "$") -> str | None:
    """The first path where two parsed JSON values differ (floats compared exactly), or None."""
    if type(a) is not type(b):
        return f"{path}: {type(a).__name__} vs {type(b).__name__}"
    if isinstance(a, dict):
        if list(a) != list(b):
            return f"{path}: keys {sorted(set(a) ^ set(b)) or 'in another order'}"
        for k in a:
            if (d := _json_diff(a[k], b[k], f"{path}.{k}")) is not None:
                return d
        return None
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{path}: {len(a)} vs {len(b)} items"
        for i, (x, y) in enumerate(zip(a, b)):
            if (d := _json_diff(x, y, f"{path}[{i}]")) is not None:
                return d
        return None
    return None if a == b else f"{path}: {a!r} vs {b!r}"


def _npz_diff(a: Path, b: Path) -> str | None:
    import numpy as np

    with np.load(a) as x, np.load(b) as y:
        if sorted(x.files) != sorted(y.files):
            return f"arrays {sorted(set(x.files) ^ set(y.files))}"
        for name in x.files:
            if x[name].shape != y[name].shape or x[name].dtype != y[name].dtype:
                return f"{name}: shape/dtype {x[name].shape} {x[name].dtype} vs {y[name].shape} {y[name].dtype}"
            if not np.array_equal(x[name], y[name], equal_nan=x[name].dtype.kind in "fc"):
                return f"{name}: values differ"
    return None


def _xlsx_diff(a: Path, b: Path) -> str | None:
    from openpyxl import load_workbook

    wa, wb = load_workbook(a, read_only=True), load_workbook(b, read_only=True)
    try:
        if wa.sheetnames != wb.sheetnames:
            return f"sheets {wa.sheetnames} vs {wb.sheetnames}"
        for name in wa.sheetnames:
            rows_a = list(wa[name].iter_rows(values_only=True))
            rows_b = list(wb[name].iter_rows(values_only=True))
            if len(rows_a) != len(rows_b):
                return f"{name}: {len(rows_a)} vs {len(rows_b)} rows"
            for i, (ra, rb) in enumerate(zip(rows_a, rows_b)):
                if ra != rb:
                    return f"{name} row {i + 1}: {ra} vs {rb}"
    finally:
        wa.close()
        wb.close()
    return None


def compare_file(a: Path, b: Path) -> str:
    """One verdict: ``identical``, ``same content`` or ``DIFFERENT (...)``."""
    if not a.is_file() or not b.is_file():
        return f"DIFFERENT (only in {'new' if b.is_file() else 'old'})"
    if a.read_bytes() == b.read_bytes():
        return "identical"
    if a.suffix == ".json":
        diff = _json_diff(json.loads(a.read_text()), json.loads(b.read_text()))
    elif a.suffix == ".npz":
        diff = _npz_diff(a, b)
    elif a.suffix == ".xlsx":
        diff = _xlsx_diff(a, b)
    else:
        diff = "bytes differ"
    return "same content" if diff is None else f"DIFFERENT ({diff})"


def compare_dirs(old: Path, new: Path) -> list[tuple[str, str]]:
    names = sorted({p.name for p in old.iterdir() if p.is_file()} | {p.name for p in new.iterdir() if p.is_file()})
    return [(name, compare_file(old / name, new / name)) for name in names]


def run_tree(tree: Path, session: Path, out: Path, extra: list[str]) -> None:
    env = dict(os.environ, PYTHONPATH=str(tree))
    done = subprocess.run([sys.executable, "-c", ENTRY, "process", str(session), "--out", str(out), *extra],
                          cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"chakamo process from {tree} failed ({done.returncode}):\n{done.stderr[-2000:]}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("dirs", nargs="*", type=Path, help="OLD_DIR NEW_DIR (or none with --session)")
    parser.add_argument("--session", type=Path, help="session folder to process from both trees")
    parser.add_argument("--old-tree", type=Path, help="checkout of the old code (with --session)")
    parser.add_argument("--new-tree", type=Path, default=Path.cwd(), help="checkout of the new code (default: .)")
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    args = parser.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    with tempfile.TemporaryDirectory(prefix="chakamo_same_") as tmp:
        if args.session is not None:
            if args.old_tree is None or args.dirs:
                parser.error("--session needs --old-tree and no OLD_DIR NEW_DIR")
            old, new = Path(tmp) / "old", Path(tmp) / "new"
            run_tree(args.old_tree.resolve(), args.session.resolve(), old, extra)
            run_tree(args.new_tree.resolve(), args.session.resolve(), new, extra)
            print(f"chakamo process {args.session} {' '.join(extra)}: {args.old_tree} (old) vs {args.new_tree} (new)")
        elif len(args.dirs) == 2:
            old, new = args.dirs
        else:
            parser.error("give OLD_DIR NEW_DIR, or --session DIR --old-tree PATH")
        rows = compare_dirs(old, new)
    width = max(len(n) for n, _ in rows)
    for name, verdict in rows:
        print(f"  {name:<{width}}  {verdict}")
    bad = [n for n, v in rows if v.startswith("DIFFERENT")]
    print("all outputs the same" if not bad else f"{len(bad)} file(s) differ: {', '.join(bad)}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
