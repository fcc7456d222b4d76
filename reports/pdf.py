"""The clinical PDF report of one knee session (fpdf2, A4, Spanish / English / Portuguese).

``render_pdf(ri) -> bytes``.  Layout, top to bottom (pages break where a block does not fit):

1. header on every page: product, report title, software version (``results["software"]["version"]``)
   and the report date, and under its rule the patient's identity (record number with its identifier system,
   birth date and age at the recordings' date, sex, clinic, the recordings' date: what is known, nothing
   invented; :func:`reports.labels.identity_line`); footer: patient name/ID and record number, "page n of N";
2. patient and session: name or ID, the identity above, session date, professional, side, step height, weight,
   height, observations (everything typed by people is printed as literal text: no markup, no formulas);
3. motor task (single-leg step-up, step height, the three phases) and protocol (sensor placement,
   magnetometer ellipsoid calibration, the orientation filter ``results["filter"]["name"]``, the sensor-to-segment
   calibration asked for and the one used, the knee-angle convention with its signs:
   :func:`reports.labels.method_items`);
4. phase table (the session task's phases, :func:`reports.labels.phase_names`; step-up: impulse,
   extension, fall: time mean ± SD in s and % of the cycle) and range-of-motion
   table (range, maximum, minimum: mean ± SD in degrees per angle);
5. mean ± SD curves over the normalised cycle with the mean phase boundaries (:mod:`reports.figures`);
   a session of both knees then shows both knees' curves overlaid and the limb symmetry index table, and one
   processed with ``--compare-with`` the earlier session's numbers beside this one's (:mod:`reports.knees`);
6. optional still of the key poses: start, peak flexion, full extension (``reports.bones.key_poses``, drawn
   as shaded vector triangles; if the geometry fails the report is written without it and the error
   logged);
7. the whole task over time, accepted cycles shaded and numbered, rejected ones hatched;
8. quality: magnetometer field and coverage per sensor, cycles accepted / rejected with the reasons,
   the posture check (angle between standing and supine), every warning; then the clinician's signed
   interpretation (the text, signer, role, date and time, "amended" with each amendment and the text it
   replaced: ``ri.interpretation``), or, before one is signed, the lines to sign by hand.

Every text comes from the translation tables through :func:`reports.i18n.t`; numbers through
:func:`reports.i18n.fmt_number` (decimal comma in es/pt).  Quality warnings are translated by their code
(:mod:`reports.warning_text`); one without a complete translation is printed in English as the software
wrote it, and then a note says so.  Figures and the key-pose still are vectors drawn with fpdf2's own
operations (:mod:`reports.figures`; a matplotlib raster cost ~100 ms per figure).
The page itself (A4, margins, font, header and footer, headings, paragraphs, tables; page totals written
after the content so no user text is ever substituted) is :mod:`reports.pdf_page`.
The output is deterministic for a given input and ``report_date``.  The font is DejaVu Sans from the installed
matplotlib package (Unicode: á, ñ, ç, °, µ, ±), embedded as a subset; :mod:`reports.fonts` gives fpdf2 a
cut of it that parses fast, or the full files when typed text needs more (a Greek or Cyrillic name).
Nothing is computed here: every number is read from ``results``.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
from collections.abc import Callable
from typing import Any

from fpdf.enums import XPos, YPos

from reports import bones, figures, fonts, knees
from reports.i18n import MISSING, fmt_date, fmt_mean_sd, fmt_number, has, t
from reports.labels import (all_excluded_lines, calibration_sentence, code_label, filter_label, get_path,
                            heading_sentence, identity_items, identity_line, method_items, phase_names, reference_sentence,
                            signature_line, signed_line, split_rejected, tr)
from reports.model import ReportInput
from reports.pdf_page import DECIMALS, FONT, GREY, ReportPDF, user_text
from reports.warning_text import warning_text

log = logging.getLogger(__name__)

ROM_ORDER = figures.ANGLE_ORDER
KEY_POSES_MAX_H_MM = 75.0


def _side_key(side: str) -> str | None:
    s = side.strip().lower()
    return {"right": "right", "r": "right", "derecho": "right", "derecha": "right", "direito": "right",
            "direita": "right", "left": "left", "l": "left", "izquierdo": "left", "izquierda": "left",
            "esquerdo": "left", "esquerda": "left"}.get(s)


def _step_height_m(ri: ReportInput) -> Any:
    """The step height typed for the patient, else the session's (``results["session"]["step_height_m"]``)."""
    p = ri.patient.step_height_m
    return p if p is not None else get_path(ri.results, "session", "step_height_m")


def _patient_block(pdf: ReportPDF, ri: ReportInput) -> None:
    p, r = ri.patient, ri.results
    side_raw = user_text(p.side) or str(r.get("side") or "")
    side_key = _side_key(side_raw)
    side = pdf.tr(f"side_{side_key}") if side_key else side_raw
    step_m = _step_height_m(ri)
    step = _step_text(pdf, step_m)
    weight = pdf.tr("value_kg", value=pdf.num(p.weight_kg, "weight_kg")) if p.weight_kg is not None else ""
    height = pdf.tr("value_m", value=pdf.num(p.height_m, "height_m")) if p.height_m is not None else ""
    none = pdf.tr("not_given")
    v = lambda s: s or none  # noqa: E731
    pairs = [(pdf.tr("patient_name"), v(user_text(p.name_or_id)))]
    pairs += [(label, user_text(value)) for label, value in identity_items(p, pdf.lang)
              if label != pdf.tr("id.patient")]
    pairs += [(pdf.tr("session_date"), v(fmt_date(user_text(p.date), pdf.lang))),
              (pdf.tr("professional"), v(user_text(p.professional))), (pdf.tr("side"), v(side)),
              (pdf.tr("step_height"), v(step)), (pdf.tr("weight"), v(weight)), (pdf.tr("height"), v(height))]
    rows = [[*pairs[i], *(pairs[i + 1] if i + 1 < len(pairs) else ("", ""))] for i in range(0, len(pairs), 2)]
    pdf.section("section_patient")
    pdf.grid(rows, (22, 28, 22, 28), headings=False, bold_cols=(0, 2))
    obs = user_text(p.observations)
    pdf.set_font(FONT, "B", 9.5)
    pdf.cell(0, 5, pdf.tr("observations"), new_x=XPos.LMARGIN, new_y=YPos.NEXT)
    pdf.paragraph(obs or none)


def _step_text(pdf: ReportPDF, step_m: Any) -> str:
    try:
        cm = float(step_m) * 100.0
    except (TypeError, ValueError):
        return ""
    if not math.isfinite(cm):
        return ""
    return pdf.tr("value_cm", value=fmt_number(cm, 0 if abs(cm - round(cm)) < 1e-6 else 1, pdf.lang))


def _task_and_protocol(pdf: ReportPDF, ri: ReportInput) -> None:
    r = ri.results
    side_raw = user_text(ri.patient.side) or str(r.get("side") or "")
    side_key = _side_key(side_raw)
    step_m = _step_height_m(ri)
    pdf.section("section_task")
    task = str(r.get("task") or "step_up")
    pdf.paragraph(pdf.tr(f"task_{task}") if has(f"task_{task}") else task, style="B")
    if task == "step_up":  # the description and the cycle definition are the step-up's
        leg = pdf.tr(f"leg_{side_key}") if side_key else (side_raw or MISSING)
        height = _step_text(pdf, step_m)
        pdf.paragraph(pdf.tr("task_description", leg=leg, height=height) if height
                      else pdf.tr("task_description_no_height", leg=leg))
        pdf.paragraph(pdf.tr("task_phases"))
    pdf.section("section_protocol")
    pdf.labelled(pdf.tr("protocol_sensors_label"), pdf.tr("protocol_sensors"))
    pdf.labelled(pdf.tr("protocol_mag_label"), pdf.tr("protocol_mag"))
    pdf.labelled(pdf.tr("protocol_filter_label"), filter_label(r, pdf.lang) or MISSING)
    # the sensor-to-segment calibration asked for and used, the angle convention: from results.json (reports.labels)
    for label, text in method_items(r, pdf.lang):
        pdf.labelled(label, text)


def _tables(pdf: ReportPDF, ri: ReportInput) -> None:
    r, lang = ri.results, pdf.lang
    phases = r.get("phases") or {}
    rows = [[pdf.tr("col_phase"), pdf.tr("col_time_s"), pdf.tr("col_pct_cycle")]]
    for name in phase_names(r):
        ph = phases.get(name) or {}
        rows.append([code_label("data.phase", name, lang),
                     fmt_mean_sd(ph.get("mean_s"), ph.get("sd_s"), DECIMALS["time_s"], lang),
                     fmt_mean_sd(ph.get("mean_pct"), ph.get("sd_pct"), DECIMALS["pct"], lang)])
    for name in ("movement", "cycle"):
        if name in phases:
            ph = phases[name] or {}
            rows.append([pdf.tr(f"phase_{name}"),
                         fmt_mean_sd(ph.get("mean_s"), ph.get("sd_s"), DECIMALS["time_s"], lang), MISSING])
    n = get_path(r, "cycles", "accepted", default=0)
    pdf.section("section_phases", space_after_mm=40)
    pdf.grid(rows, (2, 1.5, 1.5), align=("LEFT", "RIGHT", "RIGHT"), bold_cols=(0,))
    pdf.paragraph(pdf.tr("stats_note", n=n), size=8, color=GREY)

    rom = r.get("rom_deg") or {}
    rows = [[pdf.tr("col_angle"), pdf.tr("col_range"), pdf.tr("col_max"), pdf.tr("col_min")]]
    for angle in ROM_ORDER:
        a = rom.get(angle) or {}
        rows.append([pdf.tr(f"angle_{angle}")] + [
            fmt_mean_sd(get_path(a, stat, "mean"), get_path(a, stat, "sd"), DECIMALS["deg"], lang)
            for stat in ("range", "max", "min")])
    pdf.section("section_rom", space_after_mm=30)
    pdf.grid(rows, (2, 1.2, 1.2, 1.2), align=("LEFT", "RIGHT", "RIGHT", "RIGHT"), bold_cols=(0,))
    pdf.paragraph(pdf.tr("stats_note", n=n), size=8, color=GREY)


def _reference(pdf: ReportPDF, ri: ReportInput) -> None:
    """The task's reference (``results["reference"]``), when it has one: source, population, and per parameter the
    session's mean, the band (or the reference's mean when it only shows one) and the flag."""
    ref, lang = ri.results.get("reference"), pdf.lang
    if not ref:
        return
    unit = {"deg": "°", "pct": " %", "s": " s"}
    rows = [[tr("ref.parameter", lang), tr("ref.value", lang), tr("ref.band", lang), tr("ref.flag", lang)]]
    for name, p in (ref.get("parameters") or {}).items():
        u, d = unit.get(p.get("unit"), ""), DECIMALS["time_s"] if p.get("unit") == "s" else DECIMALS["deg"]
        band = (f"{fmt_number(p['low'], d, lang)}–{fmt_number(p['high'], d, lang)}{u}"
                if p.get("low") is not None and p.get("high") is not None else f"{fmt_number(p.get('mean'), d, lang)}{u}")
        flag = p.get("interpretation")
        rows.append([code_label("data.ref_param", name, lang), f"{fmt_number(p.get('value'), d, lang)}{u}", band,
                     tr(f"ref.flag_{flag}", lang) if flag else MISSING])
    pdf.section("section_reference", space_after_mm=40)
    pdf.grid(rows, (2.4, 1.1, 1.1, 1.6), align=("LEFT", "RIGHT", "RIGHT", "LEFT"), bold_cols=(0,))
    pdf.paragraph(reference_sentence(ref, lang), size=8, color=GREY)


def _figure_section(pdf: ReportPDF, ri: ReportInput, draw: Callable[..., None], height_mm: float, section: str,
                    note: str) -> None:
    """A section heading, its grey note and a full-width vector figure kept on one page; ``draw`` is one
    of :mod:`reports.figures`' ``draw_*(pdf, ri, x, y, w, h)``."""
    pdf.section(section, space_after_mm=height_mm + 8)
    pdf.paragraph(pdf.tr(note), size=8, color=GREY)
    pdf.ensure_space(height_mm + 2.0)
    y = pdf.get_y()
    draw(pdf, ri, pdf.l_margin, y, pdf.epw, height_mm)
    pdf.set_font(FONT, "", 9.5)
    pdf.set_text_color(0, 0, 0)
    pdf.set_xy(pdf.l_margin, y + height_mm + 2.0)


def _curves(pdf: ReportPDF, ri: ReportInput) -> None:
    _figure_section(pdf, ri, figures.draw_curves, figures.CURVES_HEIGHT_MM, "section_curves", "curves_note")


def _both_knees(pdf: ReportPDF, ri: ReportInput) -> None:
    """A two-knee session (:mod:`reports.knees`): left and right curves overlaid, then the LSI table."""
    r = ri.results
    h = figures.CURVES_HEIGHT_MM
    pdf.section("section.knees", space_after_mm=h + 8)
    pdf.paragraph(pdf.tr("knees.curves_note", involved=knees.involved_text(r, pdf.lang)), size=8, color=GREY)
    pdf.ensure_space(h + 2.0)
    y = pdf.get_y()
    knees.draw_knees_curves(pdf, r, pdf.lang, pdf.l_margin, y, pdf.epw, h)
    pdf.set_font(FONT, "", 9.5)
    pdf.set_text_color(0, 0, 0)
    pdf.set_xy(pdf.l_margin, y + h + 2.0)
    rows = knees.lsi_rows(r, pdf.lang)
    pdf.section("section.lsi", space_after_mm=40)
    if rows is None:
        pdf.paragraph(pdf.tr("lsi.no_involved"), size=9)
        return
    pdf.grid(rows, (2.6, 1.3, 1.3, 0.8), align=("LEFT", "RIGHT", "RIGHT", "RIGHT"), bold_cols=(0,))
    pdf.paragraph(pdf.tr("lsi.note"), size=8, color=GREY)


def _comparison(pdf: ReportPDF, ri: ReportInput) -> None:
    """An earlier session's numbers beside this one's (``results["comparison"]``, :mod:`reports.knees`)."""
    note, warning, rows = knees.comparison_table(ri.results, pdf.lang)
    pdf.section("section.compare", space_after_mm=40)
    pdf.paragraph(note, size=8, color=GREY)
    if warning:
        pdf.paragraph(warning, size=9, style="B")
    pdf.grid(rows, (2.6, 1.2, 1.2, 1.0), align=("LEFT", "RIGHT", "RIGHT", "RIGHT"), bold_cols=(0,))


def _task_over_time(pdf: ReportPDF, ri: ReportInput) -> None:
    _figure_section(pdf, ri, figures.draw_task, figures.TASK_HEIGHT_MM, "section_task_time", "task_time_note")


def _key_poses(pdf: ReportPDF, ri: ReportInput) -> bool:
    """The key-pose still (``reports.bones.key_poses``, drawn by :func:`reports.figures.draw_key_poses`);
    False when its geometry fails (the report is then written without it, the error logged)."""
    try:
        kp = bones.key_poses(ri)
    except Exception:  # a failed still must not cost the clinician the report
        log.exception("key-pose still could not be computed; the PDF is written without it")
        return False
    vx0, vx1, vy0, vy1 = kp.view
    h = min(KEY_POSES_MAX_H_MM, pdf.epw * (vy1 - vy0) / (vx1 - vx0))
    pdf.section("section_key_poses", space_after_mm=h + 4)
    pdf.ensure_space(h + 2.0)
    y = pdf.get_y()
    titles = [pdf.tr(f"pose_{k}") for k in ("start", "peak_flexion", "full_extension")]
    figures.draw_key_poses(pdf, kp, titles, pdf.lang, pdf.l_margin, y, pdf.epw, h)
    pdf.set_font(FONT, "", 9.5)
    pdf.set_text_color(0, 0, 0)
    pdf.set_xy(pdf.l_margin, y + h + 2.0)
    return True


def _quality(pdf: ReportPDF, ri: ReportInput) -> None:
    r = ri.results
    pdf.section("section_quality", space_after_mm=40)
    # magnetometer
    pdf.paragraph(pdf.tr("quality_mag"), style="B")
    mag = get_path(r, "calibration", "magnetometer", default={})
    dist = get_path(r, "quality", "magnetic_disturbance_fraction", default={})
    rows = [[pdf.tr("col_sensor"), pdf.tr("col_field_ut"), pdf.tr("col_coverage"), pdf.tr("col_residual_pct"),
             pdf.tr("col_disturbance"), pdf.tr("col_reliable")]]
    for seg in ("thigh", "shank"):
        q = get_path(mag, seg, "quality", default={})
        cov = q.get("coverage_fraction")
        d = dist.get(seg) if isinstance(dist, dict) else None
        reliable = q.get("reliable")
        rows.append([pdf.tr(f"seg_{seg}"), pdf.num(q.get("field_ut", get_path(mag, seg, "field_ut")), "field_ut"),
                     _pct(pdf, cov, "coverage_pct"), pdf.num(q.get("residual_pct"), "residual_pct"),
                     _pct(pdf, d, "disturbance_pct"),
                     MISSING if reliable is None else pdf.tr("yes" if reliable else "no")])
    pdf.grid(rows, (1.2, 1, 1.3, 1.3, 1.3, 0.8), align=("LEFT",) + ("RIGHT",) * 5, bold_cols=(0,))

    # which calibration the recordings allowed (the full protocol, no supine, the task alone; no figure-eight)
    calibration = calibration_sentence(r, pdf.lang)
    if calibration:
        pdf.ensure_space(12)
        pdf.paragraph(pdf.tr("quality_calibration"), style="B")
        pdf.paragraph(calibration)

    # which thigh–shank heading the angles use (--heading)
    heading = heading_sentence(r, pdf.lang)
    if heading:
        pdf.ensure_space(12)
        pdf.paragraph(pdf.tr("quality_heading"), style="B")
        pdf.paragraph(heading)

    # cycles
    cyc = r.get("cycles") or {}
    rejected, excluded = split_rejected(cyc)
    pdf.ensure_space(18)
    pdf.paragraph(pdf.tr("quality_cycles"), style="B")
    pdf.paragraph(pdf.tr("cycles_summary", detected=cyc.get("detected", MISSING),
                         accepted=cyc.get("accepted", MISSING), rejected=len(rejected)))
    if not rejected:
        pdf.paragraph(pdf.tr("no_rejected"))
    for rej in rejected:
        code = str(rej.get("reason") or "")
        reason = pdf.tr(f"reason_{code}") if code and has(f"reason_{code}") else (code or pdf.tr("reason_unknown"))
        idx = rej.get("index")
        pdf.paragraph("• " + pdf.tr("cycle_rejected", n=MISSING if idx is None else int(idx) + 1, reason=reason))
    for text in all_excluded_lines(r, pdf.lang):  # the clinician's (every knee's), apart from the pipeline's
        pdf.paragraph("• " + user_text(text))

    # posture check
    pdf.ln(1.5)
    pdf.ensure_space(25)
    pdf.paragraph(pdf.tr("quality_posture"), style="B")
    pdf.paragraph(pdf.tr("posture_note"), size=8, color=GREY)
    seg_cal = get_path(r, "calibration", "segment", default={})
    rows = [[pdf.tr("col_sensor"), pdf.tr("col_posture_angle")]]
    for seg in ("thigh", "shank"):
        rows.append([pdf.tr(f"seg_{seg}"), pdf.num(get_path(seg_cal, seg, "angle_between_postures_deg"), "deg")])
    pdf.grid(rows, (1, 1), align=("LEFT", "RIGHT"), bold_cols=(0,))

    # warnings, translated by code (reports.warning_text); English where no complete translation exists
    warnings = list(get_path(r, "quality", "warnings", default=[]))
    pdf.ensure_space(15)
    pdf.paragraph(pdf.tr("quality_warnings"), style="B")
    if not warnings:
        pdf.paragraph(pdf.tr("no_warnings"))
        _technical_notes(pdf, r)
        return
    texts = [warning_text(w, pdf.lang, r) for w in warnings]
    note = pdf.tr("warnings_language_note")
    if note and not all(translated for _, translated in texts):
        pdf.paragraph(note, size=8, color=GREY)
    for text, _ in texts:
        pdf.paragraph("• " + (user_text(text) or MISSING))
    _technical_notes(pdf, r)


def _technical_notes(pdf: ReportPDF, r: dict[str, Any]) -> None:
    """The notes on how the files were read (results.json ``quality.technical_notes``), small, after the warnings."""
    notes = list(get_path(r, "quality", "technical_notes", default=[]) or [])
    if not notes:
        return
    pdf.ensure_space(12)
    pdf.paragraph(pdf.tr("technical_notes"), style="B", size=8, color=GREY)
    for w in notes:
        pdf.paragraph("• " + (user_text(warning_text(w, pdf.lang, r)[0]) or MISSING), size=7, color=GREY)


def _pct(pdf: ReportPDF, fraction: Any, kind: str) -> str:
    if fraction is None or not math.isfinite(float(fraction)):
        return MISSING
    return pdf.tr("value_pct", value=pdf.num(100.0 * float(fraction), kind))


def _signature(pdf: ReportPDF) -> None:
    pdf.ensure_space(30)
    pdf.ln(10)
    y = pdf.get_y() + 8
    x0, x1 = pdf.l_margin, pdf.l_margin + 100
    pdf.set_draw_color(0, 0, 0)
    pdf.set_line_width(0.3)
    pdf.line(x0, y, x1, y)
    pdf.line(x1 + 15, y, pdf.w - pdf.r_margin, y)
    pdf.set_xy(x0, y + 1)
    pdf.set_font(FONT, "", 8.5)
    pdf.cell(100, 4, pdf.tr("signature"))
    pdf.set_xy(x1 + 15, y + 1)
    pdf.cell(0, 4, pdf.tr("signature_date"))
    pdf.set_y(y + 6)


def _signed_text(lang: str, key: str, by: str, role: str, at: str, **fields: Any) -> str:
    return user_text(signed_line(lang, key, user_text(by), role, at, **fields))


def _interpretation(pdf: ReportPDF, ri: ReportInput) -> None:
    """The clinician's signed interpretation: the text, who signed it and when, "amended" with each amendment
    (by whom, when, why) and the text it replaced, oldest first."""
    it = ri.interpretation
    pdf.section("interp.section")
    if it.amendments:
        pdf.paragraph(pdf.tr("interp.amended"), style="B", color=(170, 60, 0))
    pdf.paragraph(user_text(it.text))
    pdf.ln(1.0)
    pdf.paragraph(user_text(signature_line(pdf.lang, it)), style="B")
    if it.amendments:
        pdf.ln(1.5)
        pdf.set_font(FONT, "B", 9.5)
        pdf.cell(0, 5, pdf.tr("interp.history"), new_x=XPos.LMARGIN, new_y=YPos.NEXT)
        for a in it.amendments:
            pdf.paragraph(_signed_text(pdf.lang, "interp.amendment", a.by, a.role, a.at, reason=user_text(a.reason)),
                          size=8.5)
            pdf.paragraph(f"{pdf.tr('interp.previous')}: {user_text(a.previous_text)}", size=8.5, color=GREY)
            pdf.ln(1.0)


def _footer_patient(ri: ReportInput) -> str:
    """The footer's patient: name or ID, and the record number when it is another text."""
    p = ri.patient
    parts = [user_text(p.name_or_id)] + ([user_text(p.record_number)] if p.record_number and
                                         p.record_number != p.name_or_id else [])
    return " · ".join(x for x in parts if x)


def _data_texts(ri: ReportInput) -> list[str]:
    """Every text the report may print that is not from the translation tables: what people typed and
    the strings of ``results`` (warnings, filter name, codes) — to choose the font cut (:mod:`reports.fonts`)."""
    out = [str(v) for v in vars(ri.patient).values() if v is not None]
    if ri.interpretation is not None:
        it = ri.interpretation
        out += [it.text, it.signed_by] + [x for a in it.amendments for x in (a.previous_text, a.by, a.reason)]
    stack: list[Any] = [ri.results]
    while stack:
        item = stack.pop()
        if isinstance(item, str):
            out.append(item)
        elif isinstance(item, dict):
            stack.extend(item.keys())
            stack.extend(v for v in item.values() if isinstance(v, (str, dict, list)))
        elif isinstance(item, list):
            stack.extend(v for v in item if isinstance(v, (str, dict, list)))
    return out


def render_pdf(ri: ReportInput, *, report_date: _dt.date | None = None, key_poses: bool = True) -> bytes:
    """The PDF report of ``ri`` in ``ri.language`` (module docstring for the layout).

    report_date : the date printed in the header (default: today, UTC).
    key_poses : include the key-pose still (``reports.bones``).
    Returns the PDF file's bytes.
    """
    lang = ri.language
    report_date = report_date or _dt.datetime.now(_dt.timezone.utc).date()
    pdf = ReportPDF(lang, full_font=fonts.needs_full_font(_data_texts(ri)))
    version = str(get_path(ri.results, "software", "version", default=MISSING))
    pdf.set_title(f"{t('product', lang)} — {t('report_title', lang)}")
    pdf.set_creator(f"ChakaMo {version}")
    pdf.set_lang(lang)
    pdf.set_creation_date(_dt.datetime.combine(report_date, _dt.time(), tzinfo=_dt.timezone.utc))
    pdf.add_page()
    _patient_block(pdf, ri)
    _task_and_protocol(pdf, ri)
    _tables(pdf, ri)
    _reference(pdf, ri)
    _curves(pdf, ri)
    if knees.has_knees(ri.results):
        _both_knees(pdf, ri)
    if knees.has_comparison(ri.results):
        _comparison(pdf, ri)
    if key_poses:
        _key_poses(pdf, ri)
    _task_over_time(pdf, ri)
    _quality(pdf, ri)
    if ri.interpretation is None:
        _signature(pdf)  # lines to sign by hand
    else:
        _interpretation(pdf, ri)
    pdf.draw_page_chrome(version, fmt_date(report_date, lang), _footer_patient(ri),
                         user_text(identity_line(ri.patient, lang)))
    return bytes(pdf.output())


__all__ = ["render_pdf", "user_text", "DECIMALS"]
