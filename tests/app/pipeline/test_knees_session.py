"""Both knees in one session (issue 15 §2): four sensors named by side, or two one-knee sessions paired; each knee
processed with its own side; the limb symmetry index against the asymmetry put into the simulator.

Truth: :func:`estimators.simulation.gait.walking` with ``knee_gain={"left": 0.8}`` scales every left flexion by
0.8 (the same stride draws for both legs), so the LSI of the flexion peaks and ROM with the left knee involved is
80 %, and of the timing parameters (both legs share the stride clock) 100 %."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from app.cli.main import main
from app.pipeline.demo import accuracy, simulate_walk_knees, write_knees_session
from app.pipeline.ingestion import IngestionError, load_knees, load_session
from app.pipeline.knees import limb_symmetry, process_knees
from app.pipeline.session import PipelineError, ProcessOptions

GAIN = 0.8


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    truth = simulate_walk_knees(seed=1, knee_gain={"left": GAIN})
    folder = tmp_path_factory.mktemp("knees") / "session"
    write_knees_session(folder, truth, patient_side="left")
    return folder, truth


@pytest.fixture(scope="module")
def cli_results(walk, tmp_path_factory):
    out = tmp_path_factory.mktemp("knees_out") / "out"
    assert main(["process", str(walk[0]), "--out", str(out), "--task", "gait", "--lang", "es"]) == 0
    return out, json.loads((out / "results.json").read_text())


def test_four_sensors_through_the_cli_give_the_lsi_put_in(cli_results):
    out, r = cli_results
    # the one-knee contract at the top level: the involved knee (the patient's side in session.json)
    assert r["side"] == "left" and r["involved_side"] == "left" and r["task"] == "gait"
    assert sorted(r["knees"]) == ["left", "right"]
    assert r["knees"]["left"]["side"] == "left" and r["knees"]["right"]["side"] == "right"
    assert r["rom_deg"] == r["knees"]["left"]["rom_deg"]
    for knee in r["knees"].values():
        assert knee["cycles"]["accepted"] >= 8 and "knees" not in knee
    sym = {p["name"]: p for p in r["symmetry"]["parameters"]}
    assert r["symmetry"]["involved"] == "left" and r["symmetry"]["uninvolved"] == "right"
    for name in ("swing_peak_flexion", "flexion_rom"):
        assert sym[name]["lsi_pct"] == pytest.approx(100 * GAIN, abs=4.0), sym[name]
    for name in ("stride_time", "cadence", "stance", "swing_peak_timing"):
        assert sym[name]["lsi_pct"] == pytest.approx(100.0, abs=3.0), sym[name]
    npz = np.load(out / "timeseries.npz")
    assert npz["angles_deg_left"].shape == (len(npz["t_s_left"]), 3) and "angles_deg_right" in npz
    np.testing.assert_array_equal(npz["angles_deg"], npz["angles_deg_left"])
    for name in ("report.pdf", "angles.xlsx", "report.html"):
        assert (out / name).stat().st_size > 5_000


def test_the_reports_show_both_knees_and_the_lsi(cli_results):
    import subprocess

    import openpyxl

    out, r = cli_results
    text = subprocess.run(["pdftotext", "-layout", str(out / "report.pdf"), "-"], capture_output=True, text=True,
                          check=True).stdout
    assert "Ambas rodillas" in text and "Índice de simetría entre miembros (LSI)" in text
    swing = next(p for p in r["symmetry"]["parameters"] if p["name"] == "swing_peak_flexion")
    row = next(line for line in text.splitlines() if "Pico de flexión en el balanceo" in line)
    assert f"{swing['lsi_pct']:.1f}".replace(".", ",") in row  # the number results.json holds, decimal comma
    page = (out / "report.html").read_text()
    assert 'id="fig-knees"' in page and 'id="lsi"' in page and "Rodilla izquierda" in page
    wb = openpyxl.load_workbook(out / "angles.xlsx", read_only=True)
    assert {"Simetría", "Curvas de ambas rodillas"} <= set(wb.sheetnames)
    rows = list(wb["Simetría"].iter_rows(values_only=True))
    assert rows[0][0] == "Parámetro" and len(rows) == 1 + len(r["symmetry"]["parameters"])
    assert any(row[4] == pytest.approx(swing["lsi_pct"]) for row in rows[1:])


def test_the_patients_right_side_is_the_default_involved_knee(walk, tmp_path):
    """``session.json`` ``side: right`` and no ``--involved``: the right knee is the involved one (each knee's own
    side must not hide the patient's: the top level, the report and every LSI would describe the other knee)."""
    folder = tmp_path / "s"
    shutil.copytree(walk[0], folder)
    manifest = json.loads((folder / "session.json").read_text())
    (folder / "session.json").write_text(json.dumps({**manifest, "side": "right"}))
    knees = load_knees(folder)
    assert {s.patient_side for s in knees.values()} == {"right"}
    assert {side: s.metadata.value("side") for side, s in knees.items()} == {"left": "left", "right": "right"}
    out = tmp_path / "out"
    assert main(["process", str(folder), "--out", str(out), "--task", "gait", "--lang", "en"]) == 0
    r = json.loads((out / "results.json").read_text())
    assert r["involved_side"] == "right" and r["side"] == "right" and r["rom_deg"] == r["knees"]["right"]["rom_deg"]
    sym = {p["name"]: p["lsi_pct"] for p in r["symmetry"]["parameters"]}
    assert r["symmetry"]["involved"] == "right"
    assert sym["swing_peak_flexion"] == pytest.approx(100 / GAIN, abs=6.0)  # the right knee is the stronger one


def test_the_other_knees_warnings_reach_the_top_level_with_its_knee(walk, tmp_path):
    """The right (uninvolved) shank sensor stopped 2 s early (the right thigh's task is cut to the pair's span, a
    note) and a magnet lay by the right thigh sensor for 7 s (+30/−20 µT: a clinical warning), both of the right
    knee only.  They reach the top level (what the reports, the web and FHIR print) named as the right knee's, in
    each language; a warning both knees raise alike (no figure-eight recording) is said once."""
    import subprocess

    from app.web.fhir import diagnostic_report

    folder = tmp_path / "s"
    shutil.copytree(walk[0], folder)
    for p in folder.glob("derecha-step-pierna*.csv"):
        lines = p.read_text().splitlines(keepends=True)
        p.write_text("".join(lines[:len(lines) - (len(lines) - 1) // 7]))  # the last 2 s of 14 lost
    for p in folder.glob("derecha-step-muslo*Magnetometer*.csv"):  # tesla, 20 Hz: from 3 s to 10 s
        head, *rows = p.read_text().splitlines()
        rows = [",".join([*f[:3], f"{float(f[3]) + 30e-6:.9f}", f"{float(f[4]) - 20e-6:.9f}", *f[5:]])
                if 60 <= i < 200 else ",".join(f) for i, f in enumerate(row.split(",") for row in rows)]
        p.write_text("\n".join([head, *rows]) + "\n")
    out = tmp_path / "out"
    assert main(["process", str(folder), "--out", str(out), "--task", "gait", "--lang", "es"]) == 0
    r = json.loads((out / "results.json").read_text())
    assert r["involved_side"] == "left"
    right_only = [w for w in r["knees"]["right"]["quality"]["warnings"]
                  if w not in r["knees"]["left"]["quality"]["warnings"]]
    clinical = right_only  # the stream cut is a technical note, kept apart (and out of FHIR's conclusion)
    assert {w["code"] for w in right_only} == {"magnetic_disturbance"}
    notes_right = [w for w in r["knees"]["right"]["quality"]["technical_notes"]
                   if w not in r["knees"]["left"]["quality"]["technical_notes"]]
    assert {w["code"] for w in notes_right} == {"ingestion_note"}
    assert [w for w in r["quality"]["technical_notes"] if (w["params"] or {}).get("knee") == "right"] == \
        [{**w, "params": {**w["params"], "knee": "right"}} for w in notes_right]
    top = r["quality"]["warnings"]
    assert [w for w in top if (w["params"] or {}).get("knee") == "right"] == \
        [{**w, "params": {**w["params"], "knee": "right"}} for w in right_only]
    no_mag = [w for w in top if w["params"].get("variant") == "no_mag_calibration"]
    assert len(no_mag) == 1 and "knee" not in no_mag[0]["params"]
    text = subprocess.run(["pdftotext", "-layout", str(out / "report.pdf"), "-"], capture_output=True, text=True,
                          check=True).stdout
    assert "Rodilla derecha: " in text
    for lang, prefix in (("es", "Rodilla derecha: "), ("en", "Right knee: "), ("pt", "Joelho direito: ")):
        doc = diagnostic_report(session={"id": 1, "date": "2026-11-22", "task": "gait", "professional": "",
                                         "notes": "", "created_at": None},
                                patient={"id": 1, "external_id": "DEMO-001", "side": "left", "name": "",
                                         "birth_date": None, "sex": None},
                                results=r, pdf=b"%PDF-1.4", lang=lang, base_url="https://chakamo.example")
        assert doc["conclusion"].count(prefix) == len(clinical), (lang, doc["conclusion"])


def test_a_patient_side_that_is_no_side_is_refused(walk, tmp_path):
    folder = tmp_path / "s"
    shutil.copytree(walk[0], folder)
    (folder / "session.json").write_text(json.dumps({"side": "both"}))
    with pytest.raises(IngestionError) as err:
        load_knees(folder)
    assert err.value.code == "manifest.bad_side"


def test_the_other_knee_involved_gives_the_reciprocal(cli_results):
    r = cli_results[1]
    left = {p["name"]: p["lsi_pct"] for p in r["symmetry"]["parameters"]}
    right = {p["name"]: p["lsi_pct"] for p in limb_symmetry(r["knees"], "right")["parameters"]}
    for name, value in left.items():
        assert right[name] == pytest.approx(1e4 / value)
    assert limb_symmetry(r["knees"], None) is None and limb_symmetry({"left": r}, "left") is None


def test_each_knee_with_its_own_side_against_the_truth(walk):
    folder, truth = walk
    knees = load_knees(folder)
    assert {side: s.metadata.value("side") for side, s in knees.items()} == {"left": "left", "right": "right"}
    outcome = process_knees(knees, ProcessOptions(task="gait", involved="right"))
    assert outcome.involved == "right" and outcome.primary.side == "right"
    for side, o in outcome.knees.items():
        acc = accuracy(o, truth[side])
        # a knee processed with the other side's sign would read adduction and rotation mirrored (~2-6° RMSE more)
        assert acc["rmse_deg"]["flexion"] <= 3.0 and acc["rmse_deg"]["adduction"] <= 3.5, (side, acc)
    mirrored = process_knees({"left": knees["left"]}, ProcessOptions(task="gait", side="right"))
    assert accuracy(mirrored.primary, truth["left"])["rmse_deg"]["adduction"] > \
        accuracy(outcome.knees["left"], truth["left"])["rmse_deg"]["adduction"] + 1.0


def test_two_knees_refuse_one_side_for_both(walk):
    with pytest.raises(PipelineError) as err:
        process_knees(load_knees(walk[0]), ProcessOptions(task="gait", side="left"))
    assert err.value.code == "pipeline.side_with_two_knees" and "--involved" in err.value.message("es")
    # the web's user has no command line: the same refusal names the form's fields and the request's
    with pytest.raises(PipelineError) as err:
        process_knees(load_knees(walk[0]), ProcessOptions(task="gait", side="left"), web=True)
    assert err.value.code == "pipeline.side_with_two_knees.web"
    for lang, field in (("es", "Rodilla afectada"), ("en", "Involved knee"), ("pt", "Joelho afetado")):
        assert field in err.value.message(lang) and "--" not in err.value.message(lang)


def test_a_two_knee_folder_is_not_read_as_one_knee(walk):
    with pytest.raises(IngestionError) as err:
        load_session(walk[0])
    assert err.value.code == "session.two_knees"


def test_a_recording_without_a_side_in_a_two_knee_folder_is_refused(walk, tmp_path):
    folder = tmp_path / "s"
    shutil.copytree(walk[0], folder)
    extra = sorted(folder.glob("derecha-step-muslo*"))
    for p in extra:  # a third thigh recording, naming no side
        shutil.copy(p, p.with_name(p.name.replace("derecha-step-muslo", "standing-muslo").replace("D4F1", "AAAA")))
    with pytest.raises(IngestionError) as err:
        load_knees(folder)
    assert err.value.code == "session.side_unknown" and "standing-muslo" in err.value.params["files"]
    assert "izquierda" in err.value.message("es") and "esquerda" in err.value.message("pt")


def test_the_side_from_session_json_entries(walk, tmp_path):
    """Files that name no side, the side given per recording in ``session.json``."""
    folder = tmp_path / "s"
    folder.mkdir()
    groups: dict[str, list[str]] = {}
    for p in sorted(walk[0].glob("*.csv")):
        name = p.name.replace("izquierda-", "a-").replace("derecha-", "b-")
        shutil.copy(p, folder / name)
        groups.setdefault(name.split("_MetaWear")[0], []).append(name)
    recordings = [{"files": files, "side": "izquierda" if label.startswith("a-") else "right"}
                  for label, files in groups.items()]
    (folder / "session.json").write_text(json.dumps({"recordings": recordings}))
    knees = load_knees(folder)
    assert sorted(knees) == ["left", "right"]
    assert all(len(s.recordings) == 2 for s in knees.values())


def _split(walk_folder, tmp_path):
    """The four-sensor folder as two one-knee folders (``left/``, ``right/``)."""
    for side, word in (("left", "izquierda"), ("right", "derecha")):
        (tmp_path / side).mkdir()
        for p in walk_folder.glob(f"{word}-*.csv"):
            shutil.copy(p, tmp_path / side / p.name)
    return tmp_path / "left", tmp_path / "right"


def test_two_one_knee_sessions_paired(walk, tmp_path):
    left, right = _split(walk[0], tmp_path)
    (left / "session.json").write_text(json.dumps({"side": "left", "paired_session": "../right"}))
    knees = load_knees(left)
    assert sorted(knees) == ["left", "right"] and knees["right"].folder == right.resolve()
    assert {s.patient_side for s in knees.values()} == {"left"}
    assert list(load_knees(right)) == ["right"]  # the side from the file names; no pairing from this side


def test_a_pair_of_the_same_side_or_no_folder_is_refused(walk, tmp_path):
    left, right = _split(walk[0], tmp_path)
    (right / "session.json").write_text(json.dumps({"side": "left"}))
    (left / "session.json").write_text(json.dumps({"side": "left", "paired_session": "../right"}))
    with pytest.raises(IngestionError) as err:
        load_knees(left)
    assert err.value.code == "manifest.paired_same_side"
    (left / "session.json").write_text(json.dumps({"side": "left", "paired_session": "../nowhere"}))
    with pytest.raises(IngestionError) as err:
        load_knees(left)
    assert err.value.code == "manifest.paired_not_found" and "../nowhere" in err.value.message("pt")


def test_a_later_session_compared_with_an_earlier_one(cli_results, tmp_path):
    """``chakamo process --compare-with``: the later walk's left flexion is 90 % of the right's (80 % before), so
    the swing-peak LSI rises by 10 points; the reports show the comparison."""
    import subprocess

    earlier_out, earlier = cli_results
    folder = tmp_path / "later"
    write_knees_session(folder, simulate_walk_knees(seed=4, knee_gain={"left": 0.9}), patient_side="left")
    out = tmp_path / "out"
    assert main(["process", str(folder), "--out", str(out), "--task", "gait", "--lang", "pt",
                 "--compare-with", str(earlier_out)]) == 0
    c = json.loads((out / "results.json").read_text())["comparison"]
    assert c["comparable"] and c["with"]["filter"] == earlier["filter"]["name"]
    rows = {r["key"]: r for r in c["rows"]}
    assert rows["symmetry.swing_peak_flexion.lsi_pct"]["change"] == pytest.approx(10.0, abs=5.0)
    assert rows["rom_deg.flexion.range"]["a"] == earlier["rom_deg"]["flexion"]["range"]["mean"]
    text = subprocess.run(["pdftotext", "-layout", str(out / "report.pdf"), "-"], capture_output=True, text=True,
                          check=True).stdout
    assert "Comparação com uma sessão anterior" in text and "Mudança" in text


def test_comparing_with_something_else_is_refused_and_a_method_change_is_said(cli_results, tmp_path):
    from app.pipeline.comparison import comparison
    from app.pipeline.process import process_folder

    bad = tmp_path / "results.json"
    bad.write_text("{\"not\": \"results\"}")
    with pytest.raises(PipelineError) as err:
        process_folder(tmp_path / "nowhere", tmp_path / "out", compare_with=bad)
    assert err.value.code == "pipeline.compare_unreadable" and "results.json" in err.value.message("es")
    r = cli_results[1]
    other = {**r, "filter": {**r["filter"], "name": "madgwick"}}
    c = comparison(other, r)
    assert not c["comparable"] and c["mismatch"] == ["filter"]
    assert all(row["change"] == 0.0 for row in c["rows"] if row["change"] is not None)


def test_the_reports_show_the_other_knees_exclusions(walk, tmp_path):
    """A cycle of the uninvolved (right) knee excluded: the PDF, the HTML and the workbook name it with its knee
    (they printed only the involved knee's exclusions)."""
    import subprocess

    import openpyxl

    out = tmp_path / "out"
    assert main(["process", str(walk[0]), "--out", str(out), "--task", "gait", "--lang", "es",
                 "--exclude-cycles", "right:3", "--exclude-reason", "tropezó"]) == 0
    r = json.loads((out / "results.json").read_text())
    assert [e["cycle"] for e in r["knees"]["right"]["cycles"]["excluded"]] == [3]
    assert r["cycles"]["excluded"] == []  # the top level is the involved (left) knee
    line = "Rodilla derecha: Ciclo 3 excluido por el clínico"
    text = subprocess.run(["pdftotext", "-layout", str(out / "report.pdf"), "-"], capture_output=True, text=True,
                          check=True).stdout
    assert line in " ".join(text.split()) and "tropezó" in text
    assert line in (out / "report.html").read_text()
    wb = openpyxl.load_workbook(out / "angles.xlsx", read_only=True)
    cells = [c for ws in wb.worksheets for row in ws.iter_rows(values_only=True) for c in row if isinstance(c, str)]
    assert any(c.startswith(line) for c in cells)
