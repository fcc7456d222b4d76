"""Messages in es/en/pt from one catalogue; MetaBase files after an Excel round trip (rounded epochs)."""

import pickle
import re

import numpy as np
import pytest

from app.pipeline.ingestion import IngestionError, load_session, read_metabase_csv
from app.pipeline.ingestion.messages import CATALOGUE, LANGUAGES, placeholders, render


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory, sim_session):
    from app.pipeline.ingestion import write_session_metabase
    d = tmp_path_factory.mktemp("session")
    write_session_metabase(d, sim_session[0], patient_id="ML1", utc_offset_h=-4.0)   # names in local time
    return d


def test_every_code_has_three_languages_with_the_same_placeholders():
    for code, entry in CATALOGUE.items():
        assert set(entry) == set(LANGUAGES), code
        assert all(entry[lang].strip() for lang in LANGUAGES), code
        assert placeholders(entry["es"]) == placeholders(entry["en"]) == placeholders(entry["pt"]), code
        if not code.startswith(("word.", "hint.", "note.")):
            assert code.startswith("recording.") or code in ("xlsx.no_openpyxl", "opal.no_h5py") or "file}" in entry["en"], code


def test_every_code_raised_in_the_package_is_in_the_catalogue():
    from pathlib import Path
    import app.pipeline.ingestion as pkg
    used = set()
    for p in Path(pkg.__file__).parent.glob("*.py"):
        text = p.read_text()
        used |= set(re.findall(r'IngestionError\(\s*"([a-z_]+\.[a-z_]+)"', text))
        used |= {f"note.{v}" for v in re.findall(r'Note\.of\(\s*"([a-z_]+)"', text)}
    assert used and not used - set(CATALOGUE), sorted(used - set(CATALOGUE))


def _refusal(folder) -> IngestionError:
    with pytest.raises(IngestionError) as exc:
        load_session(folder)
    return exc.value


def test_a_real_refusal_in_each_language(folder):
    p = next(folder.glob("step-pierna*_Gyroscope_*.csv"))
    lines = p.read_text().splitlines()
    lines[60], lines[61] = lines[61], lines[60]
    p.write_text("\n".join(lines) + "\n")
    exc = _refusal(folder)
    assert exc.code == "stamp.goes_back" and exc.params["row"] == 61
    en, es, pt = (exc.message(lang) for lang in ("en", "es", "pt"))
    assert en == str(exc) and "goes back in time" in en
    assert "retrocede" in es and "Exporte de nuevo" in es and "volta atrás" in pt and "Exporte a gravação" in pt
    assert all(p.name in m and "61" in m for m in (en, es, pt))
    clone = pickle.loads(pickle.dumps(exc))                 # a job engine may pickle it
    assert clone.code == exc.code and clone.message("pt") == pt


def test_missing_recordings_in_each_language(folder):
    for p in folder.glob("standing-pierna*"):
        p.unlink()
    exc = _refusal(folder)
    assert exc.code == "session.missing_recordings"
    assert "missing recording(s): standing of the shank" in str(exc)
    assert "falta(n) grabación(es): de pie (pierna)" in exc.message("es")
    assert "falta(m) gravação(ões): em pé (perna)" in exc.message("pt")
    assert "Nomeie os ficheiros" in exc.message("pt") and "Nombre los archivos" in exc.message("es")


def test_no_recordings_says_what_the_folder_holds(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    (tmp_path / "photo.jpg").write_bytes(b"\xff\xd8")
    exc = _refusal(tmp_path)
    assert exc.code == "session.no_recordings" and "2 file(s): notes.txt, photo.jpg" in str(exc)
    assert "2 archivo(s)" in exc.message("es") and "2 ficheiro(s)" in exc.message("pt")


def test_plain_text_errors_keep_working():
    exc = IngestionError("session.json: must be a JSON object")
    assert exc.code == "text" and exc.message("es") == str(exc) == "session.json: must be a JSON object"


def test_render_survives_a_missing_parameter():
    assert "{row}" in render("file.ragged_row", {"file": "a.csv", "cells": 3, "header_cells": 6}, "es")


def test_notes_render_in_each_language(folder):
    p = next(folder.glob("step-pierna*_Gyroscope_*.csv"))
    lines = p.read_text().splitlines()
    p.write_text("\n".join(lines[:-1] + [lines[-1][:20]]))            # cut inside the last line
    note = next(n for n in load_session(folder).notes if getattr(n, "code", None) == "note.truncated_last_row")
    assert note.message("en").startswith("shank task: ") and p.name in note.message("en")
    assert note.message("es").startswith("pierna tarea: ") and "se descartó" in note.message("es")
    assert note.message("pt").startswith("perna tarefa: ") and "descartada" in note.message("pt")


# ------------------------------------------------------------------------------- Excel round trip

def _excel_epochs(path):
    """What Excel's CSV save does to MetaBase's epoch (ms): 6 significant digits, '1.63552E+12'."""
    lines = path.read_text().splitlines()
    out = [lines[0]]
    for ln in lines[1:]:
        ms, rest = ln.split(",", 1)
        out.append(f"{float(ms):.5E}".replace("E+0", "E+") + "," + rest)
    path.write_text("\n".join(out) + "\n")


def test_excel_rounded_epochs_are_rebuilt_from_elapsed_and_the_name(folder):
    truth = {p.name: read_metabase_csv(p).t_s for p in folder.glob("step-muslo*.csv")}
    for p in folder.glob("step-muslo*.csv"):
        _excel_epochs(p)
        assert "E+12" in p.read_text().splitlines()[1]
    session = load_session(folder)
    raw = session.raw[("thigh", "task")]
    for s in raw.streams:
        t = truth[s.file.name]
        assert s.time_base == "epoch" and len(s.t_s) == len(t)
        assert np.max(np.abs(s.t_s - t)) < 0.05           # the name's start is the recording's, within ms
        np.testing.assert_allclose(np.diff(s.t_s), np.diff(t), atol=2e-3)
    variants = [n.params.get("variant") for n in session.notes if hasattr(n, "params")]
    assert "excel_epoch_rebuilt" in variants and "excel_epoch_offset" in variants   # -4 h found in other files
    note = next(n for n in session.notes if getattr(n, "params", {}).get("variant") == "excel_epoch_offset")
    assert note.params["offset_h"] == pytest.approx(-4.0)
    thigh, shank = session.task_pair()
    assert len(thigh.t_s) > 100 and np.array_equal(thigh.t_s, shank.t_s)


def test_excel_rounded_epochs_in_every_file_stay_consistent(folder):
    """No file kept its epoch: both sensors on the phone's local time, still aligned with each other."""
    for p in folder.glob("*.csv"):
        _excel_epochs(p)
    session = load_session(folder)
    thigh, shank = session.task_pair()
    assert len(thigh.t_s) > 100
    assert any(getattr(n, "params", {}).get("variant") == "excel_epoch_local" for n in session.notes)


def test_excel_rounded_epochs_without_the_metabase_name_are_refused(folder):
    p = next(folder.glob("step-muslo*_Gyroscope_*.csv"))
    _excel_epochs(p)
    q = p.with_name("gyro_from_excel.csv")
    p.rename(q)
    exc = _refusal(folder)
    assert exc.code in ("metabase.stream_missing",)     # renamed out of the pattern: no longer a MetaBase stream
    assert q.name in str(exc)


def test_excel_rounded_epochs_with_semicolons_and_decimal_commas(folder):
    """Excel in Spanish: '1,63552E+12;2023-03-13T...;0,010;-0,981;...' — read, rebuilt, noted twice."""
    for p in folder.glob("step-pierna*.csv"):
        _excel_epochs(p)
        lines = p.read_text().splitlines()
        p.write_text("\n".join(ln.replace(",", ";").replace(".", ",") for ln in lines) + "\n")
    session = load_session(folder)
    variants = {n.params.get("variant") for n in session.notes if hasattr(n, "params")}
    assert {"csv_semicolon", "excel_epoch_rebuilt", "excel_epoch_offset"} <= variants
    assert 9.0 < np.nanmedian(np.linalg.norm(session.task_pair()[1].acc, axis=1)) < 10.6


def test_an_ambiguous_label_is_explained_in_each_language(folder):
    """A name that holds two roles ("standing" and "step"): the refusal says so in the reader's language, not in
    English inside a Spanish sentence."""
    for p in list(folder.glob("standing-muslo*")):
        p.rename(p.with_name(p.name.replace("standing-muslo", "standing-step-muslo")))
    exc = _refusal(folder)
    assert "names more than one role: standing ('standing'), task ('step')" in str(exc)
    assert "nombra más de un papel: standing ('standing'), task ('step')" in exc.message("es")
    assert "nomeia mais de um papel" in exc.message("pt") and "names more" not in exc.message("pt")


def test_a_message_stored_before_its_parameters_were_renamed_still_reads():
    """Review finding: ``opal.bad_shape``'s ``({n}, 3)`` became ``{expected}``; a session's check or a job's
    error stored before (``{"code", "params": {"n": ...}}``, rendered again at every read) showed a literal
    ``{expected}`` in every language."""
    stored = {"file": "walk.h5", "dataset": "/Sensors/XI-1/Accelerometer", "shape": "(200, 4)", "n": 200}
    for lang in LANGUAGES:
        text = render("opal.bad_shape", stored, lang)
        assert "(200, 3)" in text and "{" not in text, (lang, text)
    fresh = render("opal.bad_shape", {**stored, "expected": "(200,)"}, "en")
    assert "expected (200,)" in fresh  # a new message's own parameter wins
