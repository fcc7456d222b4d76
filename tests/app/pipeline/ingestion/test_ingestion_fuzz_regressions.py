"""Plain regression tests for the bugs the ingestion fuzzer (``test_ingestion_fuzz.py``) found.

Each test is the smallest case of one finding: before its fix it raised another exception type (csv.Error,
AttributeError, TypeError, IndexError, UnicodeDecodeError, a numpy overflow warning), or an IngestionError
that named another file or misled.  Every one now gives one IngestionError naming the file with advice.
"""

import json
import warnings

import numpy as np
import pytest

from app.pipeline.ingestion.metabase import parse_file_name

from app.pipeline.ingestion import IngestionError, load_session, read_metabase_csv, read_thesis_xlsx, write_metabase_csv
from app.pipeline.ingestion.excel import HEADER, _openpyxl


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory, sim_session):
    from app.pipeline.ingestion import write_session_metabase
    d = tmp_path_factory.mktemp("session")
    write_session_metabase(d, sim_session[0], patient_id="ML1", manifest={"side": "right"})
    return d


@pytest.fixture
def stream_file(tmp_path):
    """One valid MetaBase accelerometer file (2 s at 100 Hz, gravity on z)."""
    p = tmp_path / "a_MetaWear_2023-03-13T10.00.00.000_D4F1A2B3C4E5_Accelerometer_100.000Hz_1.5.1.csv"
    ms = 1_678_700_000_000 + 10 * np.arange(200)
    return write_metabase_csv(p, "acc", ms, np.tile([0.0, 0.0, 9.81], (200, 1)))


def _file(folder, label_start, stream):
    (p,) = folder.glob(f"{label_start}*_{stream}_*.csv")
    return p


def _error(call, *args) -> str:
    with pytest.raises(IngestionError) as exc:
        call(*args)
    return str(exc.value)


def test_a_cell_beyond_the_csv_field_limit(stream_file):
    """Was ``_csv.Error: field larger than field limit (131072)``."""
    lines = stream_file.read_text().splitlines()
    lines[5] = lines[5] + "1" * 140_000
    stream_file.write_text("\n".join(lines) + "\n")
    msg = _error(read_metabase_csv, stream_file)
    assert stream_file.name in msg and "damaged" in msg and "export" in msg


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le"])
def test_utf16_file_says_so(stream_file, encoding):
    """Was "not a MetaBase stream file: the header '\\x00e\\x00p...' lacks..." with no advice."""
    stream_file.write_bytes(stream_file.read_text().encode(encoding))
    msg = _error(read_metabase_csv, stream_file)
    assert stream_file.name in msg and "UTF-16" in msg and "save it again" in msg


@pytest.mark.parametrize("value", ["1e300", "-1.7e308"])
def test_huge_cell_refused_without_numpy_overflow(stream_file, value):
    """Was a ``RuntimeWarning: overflow encountered in multiply`` in the magnitude check's norm."""
    lines = stream_file.read_text().splitlines()
    cells = lines[8].split(",")
    cells[3] = value
    lines[8] = ",".join(cells)
    stream_file.write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        msg = _error(read_metabase_csv, stream_file)
    assert stream_file.name in msg and "row 9" in msg and "x-axis (g)" in msg and "fix or delete" in msg


def test_clock_back_a_day_is_named_not_called_too_short(stream_file):
    """Was "only 200 samples (-86398.01 s); the recording is too short"."""
    lines = stream_file.read_text().splitlines()
    for k in range(50, len(lines)):
        ms, rest = lines[k].split(",", 1)
        lines[k] = f"{int(ms) - 86_400_000},{rest}"
    stream_file.write_text("\n".join(lines) + "\n")
    msg = _error(read_metabase_csv, stream_file)
    assert "goes back in time" in msg and "rows 50 and 51" in msg and "too short" not in msg


@pytest.mark.parametrize("manifest,expect", [
    ({"sensors": None}, "sensors = None must be an object"),                     # was AttributeError
    ({"recordings": None}, "recordings = None must be a list"),                  # was TypeError
    ({"recordings": 3}, "recordings = 3 must be a list"),                        # was TypeError
    ({"sensors": {"D4F1A2B3C4E5": 1}}, "give the segment as a string"),
    ({"recordings": []}, "'recordings' lists no recording"),                     # named the folder only
    ({"recordings": [{"files": []}]}, "non-empty list"),                         # was IndexError
    ({"recordings": [{"files": ["x.csv"], "role": 5}]}, "(strings)"),
    ({"step_height_m": True}, "step_height_m = True must be"),
])
def test_manifest_types(folder, manifest, expect):
    (folder / "session.json").write_text(json.dumps(manifest))
    msg = _error(load_session, folder)
    assert "session.json" in msg and expect in msg


def test_manifest_not_utf8(folder):
    """Was ``UnicodeDecodeError``."""
    (folder / "session.json").write_bytes(json.dumps({"patient_id": "Pérez"}, ensure_ascii=False).encode("latin-1"))
    assert "session.json: not UTF-8 text; save it again as UTF-8" in _error(load_session, folder)


def test_manifest_listing_a_file_twice(folder):
    """Was "X and X are both the Accelerometer of recording ...", naming the data file, not session.json."""
    files = sorted(p.name for p in folder.glob("step-muslo*"))
    (folder / "session.json").write_text(json.dumps({"recordings": [{"files": files}, {"files": files}]}))
    msg = _error(load_session, folder)
    assert "session.json" in msg and "is listed twice (recordings[0] and recordings[1])" in msg


def test_stream_without_epoch_column_named(folder):
    """Was "the streams overlap for 0.00 s only" naming the recording's accelerometer file."""
    p = _file(folder, "standing-pierna", "Gyroscope")
    lines = p.read_text().splitlines()
    p.write_text("\n".join(ln.split(",", 1)[1] for ln in lines) + "\n")
    msg = _error(load_session, folder)
    assert msg.startswith(str(p)) and "has no epoch time stamps" in msg and "'epoch (ms)'" in msg


def test_stream_renamed_out_of_the_pattern_is_named(folder):
    """Was "recording ... has no Gyroscope file" without the file that was left out."""
    p = _file(folder, "laydown-muslo", "Gyroscope")
    mac = parse_file_name(p)["mac"]
    q = p.with_name(p.name.replace(f"_{mac}_", "_"))
    p.rename(q)
    msg = _error(load_session, folder)
    assert "has no Gyroscope file" in msg and f"Ignored {q.name} (not a file of a format ChakaMo reads" in msg


def test_device_name_left_out_still_joins_its_recording(folder):
    """A name without the device part (``label_date_MAC_...``) still carries label, start and MAC: it loads."""
    p = _file(folder, "laydown-muslo", "Gyroscope")
    p.rename(p.with_name(p.name.replace("_MetaWear_", "_")))
    assert len(load_session(folder).recordings) == 8


def test_upper_case_extension_is_read(folder):
    """Was: ``.CSV`` files ignored, so "missing recording(s): task of the thigh"."""
    renamed = list(folder.glob("step-muslo*"))
    assert renamed
    for p in renamed:
        p.rename(p.with_suffix(".CSV"))
    s = load_session(folder)
    assert all(f.endswith(".CSV") for f in s.recording("thigh", "task").source["files"])


def test_excel_bool_and_huge_cells_refused(tmp_path):
    """Was: TRUE/FALSE silently read as 1/0; 1e300 overflowed the magnitude check's norm."""
    for bad, expect in ((True, "holds True, which is not a number"), (1e300, "beyond any time stamp")):
        wb = _openpyxl().Workbook()
        ws = wb.active
        ws.append(HEADER)
        for k in range(200):
            ws.append([k / 100, 0.0, 0.0, 1.0, 0.1, 0.2, 0.3] + ([k / 20, 2e-5, 1e-5, -4e-5] if k < 40 else []))
        ws["C30"] = bad
        path = tmp_path / "step-muslo-ML1-13032023-1.xlsx"
        wb.save(path)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            msg = _error(read_thesis_xlsx, path)
        assert path.name in msg and "cell C30" in msg and expect in msg
