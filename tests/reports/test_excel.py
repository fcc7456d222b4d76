"""Excel workbooks: round trip of the arrays, cycle/phase labels, per-cycle table, formula injection."""

from __future__ import annotations

import math
import zipfile

import numpy as np
import openpyxl
import pytest

from reports.excel import write_angles_xlsx, write_quaternions_xlsx
from reports.labels import cycle_and_phase_per_sample, tr
from reports.model import ANGLES, Patient, ReportInput

INJECTIONS = ['=HYPERLINK("http://evil.example","click")', "+1+2", "-2+3", "@SUM(A1:A2)", "\t=1+1", "\r=1+1",
              "=cmd|' /C calc'!A0"]


def make_report_input(language: str = "es", patient: Patient | None = None, *, per_cycle: bool = True,
                      nan_rows: bool = False) -> ReportInput:
    """A small hand-made session: 12 s at 100 Hz, 3 detected cycles, the third rejected (rmse)."""
    rng = np.random.default_rng(4)
    t = np.round(np.arange(1200) * 0.01, 10)
    angles = np.column_stack([60 + 30 * np.sin(t), 3 + np.cos(2 * t), 8 * np.sin(0.5 * t)])
    if nan_rows:
        angles[10:13] = np.nan
    q = rng.normal(size=(4, 1200, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    bounds = [[1.0, 4.5], [4.5, 8.0], [8.0, 11.0]]
    events_s = [[b0, b0 + 0.5, b0 + 1.5, b0 + 2.0, b0 + 3.0] for b0, _ in bounds]
    pcs = []
    for k, (b0, b1) in enumerate(bounds):
        pcs.append({"index": k, "accepted": k < 2, "reason": None if k < 2 else "rmse", "start_s": b0, "end_s": b1,
                    "rom_deg": {a: {"max": 60.1 + k + i, "min": 1.0 / 3 + i, "range": 59.7 + k / 7 + i}
                                for i, a in enumerate(ANGLES)},
                    "phases": {"impulse": {"s": 0.5, "pct": 100 / 6}, "extension": {"s": 1.5, "pct": 50.0},
                               "fall": {"s": 1.0, "pct": 100 / 3}}})
    curves = {a: {"mean": (np.linspace(0, 1, 101) * (i + 1)).tolist(), "sd": np.full(101, 0.5 + i).tolist()}
              for i, a in enumerate(ANGLES)}
    results = {
        "side": "right", "task": "step_up", "filter": {"name": "guo", "params": {}}, "angles": list(ANGLES),
        "cycles": {"detected": 3, "accepted": 2,
                   "rejected": [{"index": 2, "reason": "rmse", "message": "cycle 3 differs <b>much</b>"}],
                   "boundaries_s": bounds, "accepted_indices": [0, 1],
                   "events": ["onset", "countermovement_peak", "far_reached", "far_left", "rest_reached"],
                   "events_s": events_s, **({"per_cycle": pcs} if per_cycle else {})},
        "rom_deg": {a: {s: {"mean": 10.0 * (i + 1) + 0.04, "sd": 1.26} for s in ("max", "min", "range")}
                    for i, a in enumerate(ANGLES)},
        "phases": {"impulse": {"mean_s": 0.5, "sd_s": 0.01, "mean_pct": 100 / 6, "sd_pct": 0.3},
                   "extension": {"mean_s": 1.5, "sd_s": 0.02, "mean_pct": 50.0, "sd_pct": 0.4},
                   "fall": {"mean_s": 1.0, "sd_s": 0.03, "mean_pct": 100 / 3, "sd_pct": 0.5}},
        "curves": curves,
        "calibration": {"magnetometer": {"thigh": {"field_ut": 45.5, "quality": {"field_ut": 45.5,
                                                                                 "coverage_fraction": 0.9}}}},
        "quality": {"warnings": [{"code": "note", "message": "a <warning> & more"}],
                    "magnetic_disturbance_fraction": {"thigh": 0.0, "shank": 0.012}},
        "software": {"version": "0.2.0"},
    }
    return ReportInput(results=results, t_s=t, angles_deg=angles,
                       q_earth_sensor={"thigh": q[0], "shank": q[1]}, q_earth_segment={"femur": q[2], "tibia": q[3]},
                       q_sensor_segment={"thigh": np.array([1.0, 0, 0, 0]), "shank": np.array([0.0, 1, 0, 0])},
                       patient=patient or Patient(name_or_id="P-001", side="right", step_height_m=0.17),
                       language=language)


def _sheet_rows(ws) -> list[tuple]:
    return list(ws.iter_rows(values_only=True))


def _angles_workbook(ri: ReportInput, tmp_path) -> openpyxl.Workbook:
    """``angles.xlsx`` of ``ri`` written under ``tmp_path`` and read back."""
    path = tmp_path / "angles.xlsx"
    write_angles_xlsx(ri, path)
    return openpyxl.load_workbook(path)


def test_angles_round_trip_and_labels(tmp_path):
    ri = make_report_input("es")
    wb = _angles_workbook(ri, tmp_path)
    assert wb.sheetnames == ["Ángulos", "Ciclos", "Curvas normalizadas", "Paciente y sesión"]
    rows = _sheet_rows(wb["Ángulos"])
    assert rows[0] == ("Tiempo (s)", "Flexión-extensión (°)", "Aducción-abducción (°)",
                       "Rotación interna-externa (°)", "Ciclo", "Fase")
    data = rows[1:]
    assert len(data) == len(ri.t_s)
    # repr-written floats read back bit-identical
    assert np.array_equal(np.array([r[0] for r in data]), ri.t_s)
    assert np.array_equal(np.array([r[1:4] for r in data], dtype=float), ri.angles_deg)
    cycle = [r[4] for r in data]
    phase = [r[5] for r in data]
    i = {x: int(round(x * 100)) for x in (0.5, 1.0, 1.49, 1.5, 2.9, 3.0, 3.99, 4.0, 4.49, 4.5, 8.0, 10.99, 11.0)}
    assert cycle[i[0.5]] is None and phase[i[0.5]] is None
    assert (cycle[i[1.0]], phase[i[1.0]]) == (1, "Impulso")            # onset is inside [onset, peak)
    assert (cycle[i[1.49]], phase[i[1.49]]) == (1, "Impulso")
    assert (cycle[i[1.5]], phase[i[1.5]]) == (1, "Extensión")           # peak → far_left
    assert (cycle[i[2.9]], phase[i[2.9]]) == (1, "Extensión")
    assert (cycle[i[3.0]], phase[i[3.0]]) == (1, "Caída")               # far_left (3.0) → rest_reached (4.0)
    assert (cycle[i[3.99]], phase[i[3.99]]) == (1, "Caída")
    assert (cycle[i[4.0]], phase[i[4.0]]) == (1, None)
    assert (cycle[i[4.49]], phase[i[4.49]]) == (1, None)                # at rest, still cycle 1
    assert (cycle[i[4.5]], phase[i[4.5]]) == (2, "Impulso")             # half-open boundaries
    assert cycle[i[8.0]] == 3 and cycle[i[10.99]] == 3                  # rejected cycles are labelled too
    assert cycle[i[11.0]] is None


def test_cycle_labels_helper_matches_events():
    ri = make_report_input("en")
    cycle, phase = cycle_and_phase_per_sample(ri)
    assert sum(c == 2 for c in cycle) == 350
    assert sum(p == "impulse" for p in phase) == 3 * 50
    assert sum(p == "extension" for p in phase) == 3 * 150
    assert sum(p == "fall" for p in phase) == 3 * 100


def test_per_cycle_curves_and_session_sheets(tmp_path):
    ri = make_report_input("en")
    wb = _angles_workbook(ri, tmp_path)
    assert wb.sheetnames == ["Angles", "Cycles", "Normalised curves", "Patient and session"]
    rows = _sheet_rows(wb["Cycles"])
    head = rows[0]
    assert head[:5] == ("Cycle", "Status", "Reason", "Start (s)", "End (s)")
    assert "Flexion-extension range (°)" in head and "Impulse (%)" in head and "Fall (s)" in head
    assert len(rows) == 4
    for row, c in zip(rows[1:], ri.results["cycles"]["per_cycle"]):
        assert row[0] == c["index"] + 1
        assert row[1] == ("Accepted" if c["accepted"] else "Rejected")
        for a in ANGLES:
            for s in ("max", "min", "range"):
                col = head.index(f"{tr('data.angle.' + a, 'en')} {s} (°)")
                assert math.isclose(row[col], c["rom_deg"][a][s], rel_tol=1e-15)
        assert math.isclose(row[head.index("Extension (%)")], c["phases"]["extension"]["pct"], rel_tol=1e-15)
    assert rows[3][2] == "Differs from the mean (RMSE)" and rows[3][-1] == "cycle 3 differs <b>much</b>"

    rows = _sheet_rows(wb["Normalised curves"])
    assert len(rows) == 102
    pct = np.array([r[0] for r in rows[1:]], dtype=float)
    assert pct[0] == 0 and pct[-1] == 100 and pct[50] == 50
    for i, a in enumerate(ANGLES):
        assert np.allclose([r[1 + 2 * i] for r in rows[1:]], ri.results["curves"][a]["mean"], rtol=1e-15, atol=0)
        assert np.allclose([r[2 + 2 * i] for r in rows[1:]], ri.results["curves"][a]["sd"], rtol=1e-15, atol=0)

    values = dict(_sheet_rows(wb["Patient and session"])[1:])
    assert values["Patient (name or ID)"] == "P-001"
    assert values["Side under study"] == "Right"
    assert values["Step height (cm)"] == 17  # one unit of step height in every report (issue 17 §3)
    assert values["Cycles detected"] == 3 and values["Cycles accepted"] == 2
    assert values["Task"] == "Single-leg step-up"


def test_missing_per_cycle_says_not_available(tmp_path):
    ri = make_report_input("pt", per_cycle=False)
    wb = _angles_workbook(ri, tmp_path)
    rows = _sheet_rows(wb["Ciclos"])
    assert rows[1][1] == "Não disponível"


def test_formula_injection_stays_text(tmp_path):
    patient = Patient(name_or_id=INJECTIONS[0], date=INJECTIONS[3], professional=INJECTIONS[2],
                      observations=INJECTIONS[1], side=INJECTIONS[6])
    wb = _angles_workbook(make_report_input("en", patient), tmp_path)
    ws = wb["Patient and session"]
    cells = {row[0].value: row[1] for row in ws.iter_rows(min_row=2)}
    expected = {"Patient (name or ID)": INJECTIONS[0], "Date": INJECTIONS[3], "Professional": INJECTIONS[2],
                "Observations": INJECTIONS[1], "Side under study": INJECTIONS[6]}
    for field, literal in expected.items():
        cell = cells[field]
        assert cell.value == literal                     # the exact text, no added quote
        assert cell.data_type == "s"                     # a string cell, never a formula
        assert cell.quotePrefix                          # Excel keeps it text when edited
    with zipfile.ZipFile(tmp_path / "angles.xlsx") as z:                  # no formula element anywhere in the workbook
        assert not any(b"<f>" in z.read(n) or b"<f " in z.read(n) for n in z.namelist() if n.endswith(".xml"))


@pytest.mark.parametrize("text", INJECTIONS)
def test_each_injection_string_reads_back_literally(tmp_path, text):
    path = tmp_path / "a.xlsx"
    write_angles_xlsx(make_report_input("es", Patient(observations=text)), path)
    ws = openpyxl.load_workbook(path)["Paciente y sesión"]
    cell = {row[0].value: row[1] for row in ws.iter_rows(min_row=2)}["Observaciones"]
    literal = text.replace("\r", "\n")            # XML stores CR as LF; everything else exactly
    assert (cell.value, cell.data_type) == (literal, "s") and cell.quotePrefix


def test_control_characters_and_nan_do_not_break_the_workbook(tmp_path):
    ri = make_report_input("es", Patient(name_or_id="Ana\x00\x07 Pérez\tñ\ud800\uffff"), nan_rows=True)
    wb = _angles_workbook(ri, tmp_path)
    values = dict(_sheet_rows(wb["Paciente y sesión"])[1:])
    assert values["Paciente (nombre o ID)"] == "Ana Pérez\tñ"
    rows = _sheet_rows(wb["Ángulos"])
    assert rows[11][1:4] == (None, None, None) and rows[11][0] == ri.t_s[10]   # NaN → empty cell, time kept
    assert rows[14][1] == ri.angles_deg[13, 0]


def test_quaternions_round_trip(tmp_path):
    ri = make_report_input("en")
    path = tmp_path / "quaternions.xlsx"
    write_quaternions_xlsx(ri, path)
    wb = openpyxl.load_workbook(path, read_only=True)
    assert wb.sheetnames == ["Sensors", "Segments", "Calibration"]
    rows = _sheet_rows(wb["Sensors"])
    assert rows[0] == ("Time (s)", "Thigh w", "Thigh x", "Thigh y", "Thigh z", "Shank w", "Shank x", "Shank y",
                       "Shank z")
    arr = np.array(rows[1:], dtype=float)
    assert np.array_equal(arr[:, 0], ri.t_s)
    assert np.array_equal(arr[:, 1:5], ri.q_earth_sensor["thigh"])
    assert np.array_equal(arr[:, 5:9], ri.q_earth_sensor["shank"])
    rows = _sheet_rows(wb["Segments"])
    assert rows[0][1] == "Femur w" and rows[0][5] == "Tibia w"
    arr = np.array(rows[1:], dtype=float)
    assert np.array_equal(arr[:, 1:5], ri.q_earth_segment["femur"])
    assert np.array_equal(arr[:, 5:9], ri.q_earth_segment["tibia"])
    cal = _sheet_rows(wb["Calibration"])
    assert cal[1][1:] == (1.0, 0.0, 0.0, 0.0) and cal[2][1:] == (0.0, 1.0, 0.0, 0.0)
    wb.close()


@pytest.mark.parametrize("lang", ["es", "pt"])
def test_quaternion_sheet_names_translated(tmp_path, lang):
    path = tmp_path / "q.xlsx"
    write_quaternions_xlsx(make_report_input(lang), path)
    names = openpyxl.load_workbook(path, read_only=True).sheetnames
    assert names[0] == "Sensores" and names[2] == {"es": "Calibración", "pt": "Calibração"}[lang]


def test_write_replaces_an_existing_file_completely(tmp_path):
    path = tmp_path / "angles.xlsx"
    path.write_bytes(b"old junk")
    write_angles_xlsx(make_report_input("en"), path)
    assert zipfile.is_zipfile(path)
    assert [p.name for p in tmp_path.iterdir()] == ["angles.xlsx"]     # no temporary file left behind


def test_the_same_input_gives_byte_identical_workbooks(tmp_path):
    """A retried processing job must store the same artefacts: no wall-clock time inside the files."""
    import time

    ri = make_report_input("es")
    for writer, name in ((write_angles_xlsx, "angles.xlsx"), (write_quaternions_xlsx, "quaternions.xlsx")):
        writer(ri, tmp_path / f"a-{name}")
        time.sleep(1.1)  # zip stamps have a 2 s resolution and core.xml 1 s: cross at least one tick
        writer(ri, tmp_path / f"b-{name}")
        assert (tmp_path / f"a-{name}").read_bytes() == (tmp_path / f"b-{name}").read_bytes(), name
        with zipfile.ZipFile(tmp_path / f"a-{name}") as z:
            core = z.read("docProps/core.xml").decode()
        assert "1980-01-01T00:00:00Z</dcterms:modified>" in core
        assert openpyxl.load_workbook(tmp_path / f"a-{name}", read_only=True).sheetnames  # still a valid workbook
