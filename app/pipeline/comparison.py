"""Two analyses of one patient side by side (issue 15 §4): the numbers both ``results.json`` hold, and the change.

Rows ``{"key", "unit", "a", "b", "change"}`` with ``change = b − a`` (``a`` the earlier session).  Keys are paths
into ``results.json``: ``rom_deg.<angle>.<max|min|range>`` (mean over the accepted cycles, deg),
``phases.<phase>.mean_pct``, ``gait.parameters.<name>.mean`` (its unit the name's suffix) and
``symmetry.<name>.lsi_pct`` (sessions of both knees).  The two should come from the same orientation filter,
pipeline version, task, sensor-to-segment calibration and knee-angle convention, else part of a change is the
method's (at 90° flexion, 5° adduction and 15° internal rotation the thesis' ZYX angles read adduction 10.1° higher
and rotation 19.8° lower: tests/app/pipeline/test_comparison.py), and describe the same knee (``side``: the
top level of a two-knee session is its involved knee), else the change is one knee against the other:
:func:`mismatch` (the one rule, the web's comparisons use it too) says which differ.  Used by the web's ``GET /patients/{id}/compare`` (:mod:`app.store.comparisons`) and by
``chakamo process --compare-with``, whose reports then show a comparison section.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from app.choices import DEFAULT_ANGLE_CONVENTION, DEFAULT_CALIBRATION

ANGLES = ("flexion", "adduction", "internal_rotation")
ROM_STATS = ("max", "min", "range")
#: what two analyses must share to be compared (module docstring)
COMPARED = ("filter", "pipeline_version", "task", "side", "calibration", "angle_method")


def mismatch(a: Mapping[str, Any], b: Mapping[str, Any]) -> list[str]:
    """The facts of :data:`COMPARED` that differ between two analyses (``{"filter", "pipeline_version", "task",
    "side", "calibration", "angle_method", ...}`` each); empty when they are comparable."""
    return [k for k in COMPARED if a.get(k) != b.get(k)]


def at(r: Any, *path: str) -> Any:
    """The value at ``path`` in nested mappings (``results.json``), None where a key is missing."""
    for key in path:
        r = r.get(key) if isinstance(r, Mapping) else None
    return r


def number(x: Any) -> float | None:
    """``x`` as a float when it is a number (not a bool), else None."""
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else None


def comparison_rows(a: Mapping[str, Any], b: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Every number both results hold, as rows ``{"key", "unit", "a", "b", "change"}`` (module docstring)."""
    def row(key: str, unit: str, x: Any, y: Any) -> dict[str, Any]:
        x, y = number(x), number(y)
        return {"key": key, "unit": unit, "a": x, "b": y, "change": None if x is None or y is None else y - x}

    rows = [row(f"rom_deg.{angle}.{stat}", "deg", at(a, "rom_deg", angle, stat, "mean"),
                at(b, "rom_deg", angle, stat, "mean")) for angle in ANGLES for stat in ROM_STATS]
    for phase in (a.get("phases") or {}):
        if phase in (b.get("phases") or {}):
            rows.append(row(f"phases.{phase}.mean_pct", "pct", at(a, "phases", phase, "mean_pct"),
                            at(b, "phases", phase, "mean_pct")))
    for name in at(a, "gait", "parameters") or {}:
        if name in (at(b, "gait", "parameters") or {}):
            unit = name.rsplit("_", 1)[-1] if not name.endswith("steps_min") else "steps_min"
            rows.append(row(f"gait.parameters.{name}.mean", unit, at(a, "gait", "parameters", name, "mean"),
                            at(b, "gait", "parameters", name, "mean")))
    sym_a = {p["name"]: p for p in (at(a, "symmetry", "parameters") or [])}
    for p in at(b, "symmetry", "parameters") or []:
        if p["name"] in sym_a:
            rows.append(row(f"symmetry.{p['name']}.lsi_pct", "pct", sym_a[p["name"]].get("lsi_pct"), p.get("lsi_pct")))
    return rows


def comparison(earlier: Mapping[str, Any], later: Mapping[str, Any]) -> dict[str, Any]:
    """``results.json`` ``comparison`` of the later analysis against an earlier one: ``{"with": {"date",
    "patient_id", "filter", "pipeline_version", "task", "side", "calibration", "angle_method"}, "comparable",
    "mismatch", "rows"}`` (results written before the options were recorded ran with the defaults)."""
    def facts(r: Mapping[str, Any]) -> dict[str, Any]:
        session = r.get("session") or {}
        return {"date": session.get("date"), "patient_id": session.get("patient_id"),
                "filter": (r.get("filter") or {}).get("name"), "pipeline_version": (r.get("software") or {}).get("version"),
                "task": r.get("task"), "side": r.get("side"),
                "calibration": r.get("calibration_method", DEFAULT_CALIBRATION),
                "angle_method": r.get("angle_method", DEFAULT_ANGLE_CONVENTION)}

    a, b = facts(earlier), facts(later)
    differ = mismatch(a, b)
    return {"with": a, "comparable": not differ, "mismatch": differ, "rows": comparison_rows(earlier, later)}


__all__ = ["COMPARED", "at", "comparison", "comparison_rows", "mismatch", "number"]
