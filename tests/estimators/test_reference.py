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
            assert band.low == pytest.approx(band.mean - 2 * band.sd) and band.high == pytest.approx(band.mean + 2 * band.sd)
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
    block = ref.compare(ref.GAIT, {"swing_peak_flexion_deg": 50.0, "stance_min_flexion_deg": 4.0,
                                   "stance_pct": float("nan")})
    p = block["parameters"]
    assert p["swing_peak_flexion_deg"]["interpretation"] == "L" and p["swing_peak_flexion_deg"]["within_band"] is False
    assert p["stance_min_flexion_deg"]["within_band"] is True
    assert p["stance_pct"]["value"] is None and p["stance_pct"]["within_band"] is None
    assert block["outside"] == ["swing_peak_flexion_deg"]
    assert "Perry" in block["source"] and block["kind"] == "normative" and len(block["keypoints"]) == 3
