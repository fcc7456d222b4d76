"""Reference values (issue 15 §3): the thesis' step-up tables as printed (seed 004 Tables 8.1–8.4), the gait key
ranges, and the band comparison (R1)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from estimators.motor_task import reference as ref

SEEDS = Path(__file__).resolve().parents[3] / "shared" / "seeds"  # ../shared beside the repository
SEED_004 = next(iter(sorted(SEEDS.glob("004_*.txt"))), None)


@pytest.mark.skipif(SEED_004 is None, reason="../shared/seeds is not beside the repository")
def test_step_up_values_are_the_thesis_tables_as_printed():
    text = SEED_004.read_text(encoding="utf-8")
    for height, table_phases, table_rom in ((0.17, "Tabla 8.1", "Tabla 8.2"), (0.34, "Tabla 8.3", "Tabla 8.4")):
        r = ref.reference_for("step_up", height)
        before = text[:text.index(table_phases)]
        rows = {m.group(1): (float(m.group(2)), float(m.group(3)), float(m.group(4)), float(m.group(5)))
                for m in re.finditer(r"(Tarea Motora completa|Impulso|Extensión|Caída)(?:</b>)?\t([\d.]+)\t([\d.]+)\t"
                                     r"([\d.]+)\t([\d.]+)", before[-700:])}
        assert (r.parameters["cycle_s"].mean, r.parameters["cycle_s"].sd) == rows["Tarea Motora completa"][:2]
        for name, row in (("impulse", "Impulso"), ("extension", "Extensión"), ("fall", "Caída")):
            band = r.parameters[f"{name}_pct"]
            assert (band.mean, band.sd) == rows[row][2:]
            assert band.low is None and band.high is None and not band.flag  # shown, not flagged (below)
        rom = re.search(r"Flexión - extensión \(x\)(?:</b>)?\t([-\d.]+)\t([-\d.]+)\t([-\d.]+)",
                        text[:text.index(table_rom)][-900:])
        assert (r.parameters["flexion_rom_deg"].mean, r.parameters["flexion_max_deg"].mean,
                r.parameters["flexion_min_deg"].mean) == tuple(float(x) for x in rom.groups())


def test_the_step_height_picks_the_nearest_table_and_other_tasks_have_none():
    assert ref.reference_for("step_up", 0.2).conditions.endswith("17 cm step")
    assert ref.reference_for("step_up", 0.3).conditions.endswith("34 cm step")
    assert ref.reference_for("step_up", None).conditions.endswith("17 cm step")
    assert ref.reference_for("gait") is ref.GAIT and ref.reference_for("squat") is None


def test_interpretation_is_low_normal_or_high_and_none_without_a_flag():
    band = ref.Band(15.0, 20.0, "deg")
    assert [ref.interpretation(v, band) for v in (14.9, 15.0, 20.0, 20.1)] == ["L", "N", "N", "H"]
    assert ref.interpretation(None, band) is None and ref.interpretation(math.nan, band) is None
    assert ref.interpretation(100.0, ref.Band(None, None, "deg", 81.96, None, False)) is None


def test_compare_flags_the_values_outside_and_keeps_the_source():
    block = ref.compare(ref.GAIT, {"flexion_rom_deg": 50.0, "swing_peak_timing_pct": 71.0,
                                   "stance_pct": float("nan")})
    p = block["parameters"]
    assert p["flexion_rom_deg"]["interpretation"] == "L" and p["flexion_rom_deg"]["within_band"] is False
    assert p["swing_peak_timing_pct"]["within_band"] is True
    assert p["stance_pct"]["value"] is None and p["stance_pct"]["within_band"] is None
    assert block["outside"] == ["flexion_rom_deg"]
    assert "Perry" in block["source"] and block["kind"] == "normative" and len(block["keypoints"]) == 3


def test_the_gait_absolute_angles_are_shown_without_a_flag():
    """ChakaMo's flexion is zero at the standing knee, Perry & Burnfield's at the bones: the simulated walker stands
    at 2° (:mod:`estimators.simulation.gait`), so its normal stance minimum reads 1.98° and was flagged "L".  Only
    what does not depend on the zero (ROM, timing and stance %) is flagged; the absolute angles keep their band."""
    block = ref.compare(ref.GAIT, {"stance_min_flexion_deg": 1.98, "loading_response_peak_flexion_deg": 13.0,
                                   "swing_peak_flexion_deg": 58.0, "flexion_rom_deg": 56.0, "stance_pct": 60.0,
                                   "swing_peak_timing_pct": 71.0})
    p = block["parameters"]
    for name in ("stance_min_flexion_deg", "loading_response_peak_flexion_deg", "swing_peak_flexion_deg"):
        assert p[name]["interpretation"] is None and p[name]["within_band"] is None, name
        assert p[name]["low"] is not None and p[name]["high"] is not None  # the band is still shown
    assert {n: q["interpretation"] for n, q in p.items() if q["interpretation"]} == {
        "flexion_rom_deg": "N", "stance_pct": "N", "swing_peak_timing_pct": "N"}
    assert block["outside"] == []


@pytest.mark.parametrize("height", [0.17, 0.34])
def test_the_single_study_step_up_is_shown_and_never_flagged(height):
    """The thesis' step-up is one subject's cycles: its ± 2 SD (3.36–3.40 s at 17 cm) is no population range and
    flagged the demo's correct 3.35 s cycle "L".  Every value is shown (the subject's mean) with no L/N/H."""
    r = ref.reference_for("step_up", height)
    assert r.kind == "single_study" and all(not b.flag for b in r.parameters.values())
    block = ref.compare(r, {"cycle_s": 3.35, "impulse_pct": 20.0, "extension_pct": 45.0, "fall_pct": 35.0,
                            "flexion_rom_deg": 60.0, "flexion_max_deg": 61.0, "flexion_min_deg": 1.0})
    assert all(p["interpretation"] is None and p["within_band"] is None for p in block["parameters"].values())
    assert block["outside"] == [] and block["parameters"]["cycle_s"]["mean"] in (3.38, 3.54)
