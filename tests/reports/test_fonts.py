"""The PDF's font cut (reports.fonts): covers every translated text, is cached, falls back to the full font.

(That a name outside the cut prints is tested with the PDF: tests/reports/test_pdf.py.)"""

from __future__ import annotations

import pytest
from fontTools import ttLib

from reports import fonts, i18n


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """reports.fonts with its per-process caches emptied and the cache folder in tmp_path."""
    monkeypatch.setenv("CHAKAMO_FONT_CACHE", str(tmp_path / "fonts"))
    fonts._subset_files.cache_clear()
    fonts.subset_codepoints.cache_clear()
    yield tmp_path / "fonts"
    fonts._subset_files.cache_clear()
    fonts.subset_codepoints.cache_clear()


def test_the_cut_covers_every_translated_text():
    chars = {ord(c) for texts in i18n.table().values() for text in texts.values() for c in text}
    missing = sorted(chr(c) for c in chars - fonts.subset_codepoints())
    assert not missing


def test_the_cut_is_made_once_and_reused(fresh_cache):
    files = fonts.font_files()
    assert set(files) == {"", "B"} and all(p.parent == fresh_cache and p.is_file() for p in files.values())
    font = ttLib.TTFont(str(files[""]))
    assert 300 < len(font.getGlyphOrder()) < 1000 and ord("ñ") in font.getBestCmap()
    assert "DejaVu" in font["name"].getBestFamilyName()
    stamp = {p: p.stat().st_mtime_ns for p in files.values()}
    fonts._subset_files.cache_clear()                       # a new process: found on disk, not made again
    assert fonts.font_files() == files and {p: p.stat().st_mtime_ns for p in files.values()} == stamp
    assert fonts.font_files(full=True)[""] == fonts.SOURCE_DIR / "DejaVuSans.ttf"


def test_an_unwritable_cache_falls_back_to_a_temporary_folder(fresh_cache):
    fresh_cache.parent.mkdir(parents=True, exist_ok=True)
    fresh_cache.write_text("a file where the folder should be")
    files = fonts.font_files()
    assert all(p.is_file() and fresh_cache not in p.parents for p in files.values())


def test_typed_text_outside_the_cut_selects_the_full_font():
    assert not fonts.needs_full_font(["José Muñoz-Conceição", "Begoña", "72,5 kg ± 0,3°"])
    assert fonts.needs_full_font(["Αθηνά Παπαδοπούλου"])        # Greek capitals: in DejaVu, not in the cut
    assert fonts.needs_full_font(["Иван Петров"])
    assert not fonts.needs_full_font(["患者 7"])                  # not in DejaVu at all: the cut is as good


def test_font_files_come_from_matplotlib_without_importing_it():
    import subprocess
    import sys

    code = ("import sys; from reports import fonts; print('matplotlib' in sys.modules); "
            "import matplotlib; print(fonts.SOURCE_DIR == __import__('pathlib').Path(matplotlib.get_data_path()) "
            "/ 'fonts' / 'ttf')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "True"]
