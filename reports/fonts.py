"""The PDF's font files: DejaVu Sans (regular, bold) from the installed matplotlib, cut to the glyphs a
report needs.

matplotlib is only the place the files come from: its ``mpl-data`` folder is found from the package's
location (``importlib.util.find_spec``) without importing it, which cost ~0.12 s (pyparsing, rcParams)
of every process that writes a report.

Why a subset: fpdf2 parses the whole TrueType file of every font a document adds (DejaVu Sans has 6,000
glyphs) and subsets it again when it writes the file, for every report.  A ~440-glyph cut (ASCII,
Latin-1, Latin Extended-A, Greek small letters, general punctuation and the symbols the translations use:
° ± µ – — … • → ≤ ≥ ≈ −) makes a two-style document ~4× quicker to set up and write (measured: 141 ms →
34 ms on a loaded 2-core machine).

Decisions:

* The cut is made with fontTools (an fpdf2 dependency) once and kept in a per-user cache folder
  (``$XDG_CACHE_HOME/chakamo/fonts``, default ``~/.cache/chakamo/fonts``; ``CHAKAMO_FONT_CACHE`` overrides),
  named after the source file's size and modification time, fontTools' version and :data:`SUBSET_VERSION`,
  so a matplotlib or fontTools upgrade makes a new one.  Files are written to a temporary name and renamed
  (concurrent processes never read half a file).  Making it costs ~0.3 s once per machine.
* If the folder cannot be written, the cut goes to a temporary folder for this process; if fontTools
  fails, the full files are used (slower, same output).
* Text a person typed may hold characters outside the cut (a Greek or Cyrillic name): the report then
  uses the full files (:func:`font_files` with ``full=True``); characters missing from DejaVu Sans
  altogether print as fpdf2's missing-glyph box, as before.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import tempfile
from collections.abc import Iterator
from functools import lru_cache
from pathlib import Path

log = logging.getLogger(__name__)


def _matplotlib_data_dir() -> Path:
    """matplotlib's ``mpl-data`` folder (what ``matplotlib.get_data_path()`` returns), found without importing it."""
    spec = importlib.util.find_spec("matplotlib")
    locations = list(spec.submodule_search_locations or []) if spec is not None else []
    for location in locations:
        candidate = Path(location) / "mpl-data"
        if candidate.is_dir():
            return candidate
    import matplotlib  # an unusual installation layout: ask matplotlib itself

    return Path(matplotlib.get_data_path())


SOURCE_DIR = _matplotlib_data_dir() / "fonts" / "ttf"
#: style ("" regular, "B" bold) → DejaVu file name in matplotlib's data
SOURCE_FILES = {"": "DejaVuSans.ttf", "B": "DejaVuSans-Bold.ttf"}
#: bump when the ranges or the subsetting options change
SUBSET_VERSION = 1
#: code points kept in the cut (inclusive ranges)
SUBSET_RANGES: tuple[tuple[int, int], ...] = (
    (0x0020, 0x007E), (0x00A0, 0x017F),          # ASCII, Latin-1, Latin Extended-A
    (0x0394, 0x0394), (0x03B1, 0x03C9),          # Δ, Greek small letters (µ-like symbols, α, σ...)
    (0x2010, 0x2027), (0x2030, 0x203A),          # dashes, quotes, bullet, ellipsis, per mille, guillemets
    (0x20AC, 0x20AC), (0x2122, 0x2122),          # €, ™
    (0x2190, 0x2193),                            # arrows
    (0x2212, 0x2212), (0x221E, 0x221E), (0x2248, 0x2248), (0x2260, 0x2260), (0x2264, 0x2265),  # − ∞ ≈ ≠ ≤ ≥
    (0x25CF, 0x25CF),                            # ●
)


def _cache_dirs() -> Iterator[Path]:
    """Where to keep the cut: the per-user cache folder, else (lazily) a temporary folder for this process."""
    override = os.environ.get("CHAKAMO_FONT_CACHE")
    try:
        base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    except RuntimeError:                # no home directory (some service accounts)
        base = None
    if override:
        yield Path(override)
    elif base:
        yield Path(base) / "chakamo" / "fonts"
    yield Path(tempfile.mkdtemp(prefix="chakamo-fonts-"))


def _subset_name(source: Path) -> str:
    import fontTools

    st = source.stat()
    return f"{source.stem}-v{SUBSET_VERSION}-{st.st_size}-{st.st_mtime_ns}-ft{fontTools.version}.ttf"


def _make_subset(source: Path, target: Path) -> None:
    """Write the cut of ``source`` to ``target`` (temporary name, then an atomic rename)."""
    from fontTools import subset, ttLib

    font = ttLib.TTFont(str(source), recalcTimestamp=False, lazy=True)
    cmap = font.getBestCmap()
    keep = [c for c in cmap if any(lo <= c <= hi for lo, hi in SUBSET_RANGES)]
    options = subset.Options()
    options.notdef_outline = True       # fpdf2 expects a .notdef glyph
    options.layout_features = []        # fpdf2 does not shape text (no GSUB/GPOS needed)
    options.drop_tables += ["GSUB", "GPOS", "GDEF", "kern", "FFTM"]
    options.hinting = False             # PDF viewers do not use TrueType hinting at screen sizes
    options.name_IDs = ["*"]            # keep the family name and the licence text
    options.glyph_names = True
    subsetter = subset.Subsetter(options)
    subsetter.populate(unicodes=keep)
    subsetter.subset(font)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            font.save(f)
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


@lru_cache(maxsize=1)
def _subset_files() -> dict[str, Path] | None:
    """The cut files (made if absent), or None when they cannot be made."""
    out: dict[str, Path] = {}
    for folder in _cache_dirs():
        try:
            for style, name in SOURCE_FILES.items():
                source = SOURCE_DIR / name
                target = folder / _subset_name(source)
                if not target.is_file():
                    _make_subset(source, target)
                out[style] = target
            return out
        except OSError as exc:          # unwritable cache: try the process's temporary folder
            log.info("font cache %s not usable (%s); trying a temporary folder", folder, exc)
        except Exception:               # a fontTools failure must not cost the report: full fonts
            log.exception("could not cut the report font; the full DejaVu Sans files are used")
            return None
    return None


@lru_cache(maxsize=1)
def subset_codepoints() -> frozenset[int]:
    """The code points both cut files cover (empty when there is no cut)."""
    from fontTools import ttLib

    files = _subset_files()
    if files is None:
        return frozenset()
    cmaps = [set(ttLib.TTFont(str(path), lazy=True).getBestCmap()) for path in files.values()]
    return frozenset(set.intersection(*cmaps))


@lru_cache(maxsize=1)
def _full_codepoints() -> frozenset[int]:
    from fontTools import ttLib

    cmaps = [set(ttLib.TTFont(str(SOURCE_DIR / name), lazy=True).getBestCmap()) for name in SOURCE_FILES.values()]
    return frozenset(set.union(*cmaps))


def font_files(*, full: bool = False) -> dict[str, Path]:
    """``{"": regular, "B": bold}`` TrueType paths for the PDF: the cut, or the full DejaVu Sans files when
    ``full`` or when the cut cannot be made."""
    files = None if full else _subset_files()
    return files if files is not None else {style: SOURCE_DIR / name for style, name in SOURCE_FILES.items()}


def needs_full_font(texts: list[str]) -> bool:
    """Whether a character of ``texts`` is missing from the cut but drawn by the full DejaVu Sans."""
    chars = {ord(c) for s in texts for c in s} - subset_codepoints()
    return bool(chars) and bool(chars & _full_codepoints())
