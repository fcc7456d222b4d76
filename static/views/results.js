// Results of one session (#/sessions/{id}[?analysis_id=N]): the analysis selector (one analysis per
// filter run; earlier ones are kept), mean ± SD curves, ROM and phase tables, quality warnings, downloads,
// and the 3D animation in viser's static client.  A session of both knees adds the two knees' curves overlaid
// and the limb symmetry index table; any session can be compared with another of the patient's
// (GET /patients/{id}/compare: the numbers side by side, the change, and whether the two are comparable).
//
// Everything shown comes from results.json (GET /sessions/{id}/results) — the UI computes nothing clinical.
// The 3D view is an <iframe> of /viser/index.html?playbackPath=<the session's scene.viser URL> (same origin,
// so the session cookie goes along), with a jump-to-cycle control: scene.js.

import { api, apiUrl } from "../api.js";
import { h, clear, alertBox, errorText, date, dateTime, meanSd, label, num } from "../dom.js";
import { t, lang, LANGUAGES } from "../i18n.js";
import { ANGLES, drawCurve, loadPlotly, purge } from "../charts.js";
import { patientTitle, statusBadge } from "./patients.js";
import { navigate, canEdit } from "../app.js";
import { cyclesSection, technicalNotes } from "./cycles.js";
import { pairingSection } from "./pairing.js";
import { sceneSection, stillImage } from "./scene.js";

/** The results page of session `sessionId`; `query` may carry analysis_id. */
export function resultsView(sessionId, query) {
  const section = h("section", { class: "view results" }, h("p", { class: "loading" }, t("common.loading")));
  (async () => {
    let session, patient;
    try {
      session = await api("GET", `/sessions/${sessionId}`);
      patient = await api("GET", `/patients/${session.patient_id}`);
    } catch (err) {
      clear(section).append(h("h1", {}, t("results.title")), alertBox(errorText(err)),
        h("p", {}, h("a", { href: "#/patients" }, t("common.back_to_patients"))));
      return;
    }
    const analyses = [...(session.analyses || [])].sort((a, b) => b.id - a.id);
    const head = [
      h("nav", { class: "crumbs", "aria-label": t("common.breadcrumbs") },
        h("a", { href: "#/patients" }, t("nav.patients")), " › ",
        h("a", { href: `#/patients/${patient.id}` }, patientTitle(patient))),
      h("div", { class: "title-row" },
        h("h1", {}, t("results.title_session", { date: date(session.date) })), statusBadge(session.status),
        h("a", { href: `#/sessions/${sessionId}/wizard`, class: "button-link secondary" }, t("results.reprocess"))),
    ];
    if (!analyses.length) {
      clear(section).append(...head, h("div", { class: "card" }, h("p", {}, t("results.none")),
        h("a", { href: `#/sessions/${sessionId}/wizard`, class: "button-link primary" }, t("results.open_wizard"))),
      pairingSection(session, patient));
      return;
    }
    const wanted = Number(query.get("analysis_id"));
    const analysis = analyses.find((a) => a.id === wanted) || analyses[0];
    const body = h("div", { class: "results-body" }, h("p", { class: "loading" }, t("common.loading")));
    const superseded = analysis.superseded_at   // Node.append would print a null: only the notice, when due
      ? [h("div", { class: "notice warning", role: "status", id: "superseded" }, t("results.superseded"))] : [];
    clear(section).append(...head, ...superseded, analysisSelector(sessionId, analyses, analysis), body);
    const still = stillImage(sessionId, analysis.id);   // its request goes beside the results' (scene.js)
    let results, warnings;
    try {
      // the warnings in every language come beside results.json (GET .../warnings); without them, English
      [results, warnings] = await Promise.all([
        api("GET", `/sessions/${sessionId}/results`, { query: { analysis_id: analysis.id } }),
        api("GET", `/sessions/${sessionId}/warnings`, { query: { analysis_id: analysis.id } }).catch(() => null)]);
    } catch (err) {
      clear(body).append(alertBox(errorText(err)));
      return;
    }
    renderResults(body, session, patient, analysis, results, section, warnings, still);
  })();
  return section;
}

function analysisSelector(sessionId, analyses, current) {
  const select = h("select", { id: "analysis", name: "analysis_id" }, analyses.map((a) => h("option",
    { value: String(a.id), selected: a.id === current.id },
    t("results.analysis_option", { id: a.id, filter: label("filter", a.filter),
      angles: label("angle_convention", a.angle_method), date: dateTime(a.created_at),
      cycles: a.accepted_cycles ?? "—" }))));
  // at a tablet's width the chosen analysis ends in an ellipsis (style.css): its title holds it whole
  select.title = select.selectedIndex >= 0 ? select.options[select.selectedIndex].text : "";
  select.addEventListener("change", () => navigate(`#/sessions/${sessionId}?analysis_id=${select.value}`));
  return h("div", { class: "card toolbar analysis-picker" },
    h("label", { for: "analysis" }, t("results.analysis")), select,
    analyses.length > 1 ? h("span", { class: "hint" }, t("results.analyses_n", { n: analyses.length })) : null);
}

/** The sensor-to-segment calibration the pipeline used (results.json `calibration.protocol.segment`: one code, or
 *  one per segment), and the one asked for when the recordings allowed another (a session without a supine
 *  recording is calibrated on the task): what the reports' method line says (reports.labels.method_items). */
export function calibrationUsed(r, analysis) {
  const asked = r.calibration_method || analysis.calibration;
  const seg = ((r.calibration || {}).protocol || {}).segment;
  const used = typeof seg === "string" ? [seg] : (Array.isArray(seg) ? seg : []);
  if (!used.length) return label("calibration", asked);
  const text = [...new Set(used)].map((c) => label("calibration", c)).join(" / ");
  return asked && used.some((c) => c !== asked) ? `${text} (${t("results.calibration_asked", { asked: label("calibration", asked) })})` : text;
}

function renderResults(body, session, patient, analysis, r, section, warnings, still) {
  const cycles = r.cycles || {};
  const summary = h("div", { class: "card summary" }, h("dl", { class: "details inline" },
    [[t("patient.side"), label("side", r.side || patient.side)],
      [t("results.filter"), label("filter", (r.filter && r.filter.name) || analysis.filter)],
      // the convention and calibration the numbers were computed with (a ZYX run reads other angles of one knee)
      [t("wizard.angle_convention"), label("angle_convention", r.angle_method || analysis.angle_method)],
      [t("wizard.calibration"), calibrationUsed(r, analysis)],
      [t("results.cycles"), t("results.cycles_value", { accepted: cycles.accepted ?? "—", detected: cycles.detected ?? "—" })],
      [t("session.step_height"), session.step_height_m ? `${num(session.step_height_m * 100, 0)} cm` : "—"],
      [t("results.software"), (r.software && r.software.version) || "—"]]
      .map(([k, v]) => h("div", {}, h("dt", {}, k), h("dd", {}, v)))));

  const charts = ANGLES.map((a) => h("div", { class: "chart", id: `curve-${a}`, role: "img",
    "aria-label": t("results.curve_alt", { angle: label("angle", a) }) }));
  const curves = h("section", { class: "card", "aria-labelledby": "h-curves" },
    h("h2", { id: "h-curves" }, t("results.curves")), h("p", { class: "hint" }, t("results.curves_hint")),
    h("div", { class: "charts" }, charts));

  const scene = sceneSection(session.id, analysis.id, r, still);
  const knees = kneesSection(r);
  const kneeCharts = knees ? [...knees.querySelectorAll(".chart")] : [];
  clear(body).append(summary, curves, ...(knees ? [knees] : []),
    h("div", { class: "columns" },
      h("section", { class: "card grow", "aria-labelledby": "h-rom" }, h("h2", { id: "h-rom" }, t("results.rom")), romTable(r)),
      h("section", { class: "card grow", "aria-labelledby": "h-phases" }, h("h2", { id: "h-phases" }, t("results.phases")), phaseTable(r))),
    r.reference ? referenceSection(r.reference) : null,
    cyclesSection(session, analysis, r),
    qualitySection(r, warnings),
    compareSection(session, analysis),
    interpretationSection(session, analysis),
    pairingSection(session, patient),
    downloadsSection(session.id, analysis.id),
    scene);

  // the charts (plotly: 1.5-3 s of evaluation on the main thread) start once the 3D view's still first frame is
  // painted, or could not be, within 1.5 s at most (scene.js)
  scene.firstFrame.then(() => {
    if (!section.isConnected) return;
    ANGLES.forEach((a, i) => {
      const keys = a === "flexion" ? (r.reference || {}).keypoints : null;
      drawCurve(charts[i], a, (r.curves || {})[a], r.phases, keys).catch((err) => charts[i].replaceWith(alertBox(errorText(err))));
    });
    ANGLES.forEach((a, i) => {
      if (kneeCharts[i]) drawKnees(kneeCharts[i], a, r.knees).catch((err) => kneeCharts[i].replaceWith(alertBox(errorText(err))));
    });
  });
  const observer = new MutationObserver(() => {
    if (!section.isConnected) { charts.forEach(purge); kneeCharts.forEach(purge); observer.disconnect(); }
  });
  observer.observe(document.getElementById("main"), { childList: true });
}

const SIDE_COLOURS = { left: "#1f4e79", right: "#d66e16" };

/** Both knees (results.json `knees`, `symmetry`): each angle's two mean curves overlaid, and the LSI table. */
function kneesSection(r) {
  if (!r.knees || Object.keys(r.knees).length !== 2) return null;
  const charts = ANGLES.map((a) => h("div", { class: "chart", id: `knees-${a}`, role: "img",
    "aria-label": t("knees.curve_alt", { angle: label("angle", a) }) }));
  const involved = r.involved_side ? label("side", r.involved_side) : t("knees.none_involved");
  return h("section", { class: "card", id: "knees", "aria-labelledby": "h-knees" },
    h("h2", { id: "h-knees" }, t("knees.title")), h("p", { class: "hint" }, t("knees.hint", { involved })),
    h("div", { class: "charts" }, charts), lsiTable(r));
}

function lsiTable(r) {
  const sym = r.symmetry;
  if (!sym) return h("p", { class: "notice", id: "lsi-none" }, t("knees.lsi_none"));
  const unit = (u) => t(`knees.unit.${u}`);
  const value = (x, u, d) => (typeof x === "number" ? `${num(x, d)} ${unit(u)}` : "—");
  return h("table", { class: "data", id: "lsi-table" },
    h("thead", {}, h("tr", {}, h("th", { scope: "col" }, t("knees.parameter")),
      h("th", { scope: "col", class: "num" }, t("knees.involved", { side: label("side", sym.involved) })),
      h("th", { scope: "col", class: "num" }, t("knees.uninvolved", { side: label("side", sym.uninvolved) })),
      h("th", { scope: "col", class: "num" }, t("knees.lsi")))),
    h("tbody", {}, sym.parameters.map((p) => h("tr", {}, h("th", { scope: "row" }, t(`knees.param.${p.name}`)),
      h("td", { class: "num" }, value(p.involved, p.unit, p.unit === "s" ? 2 : 1)),
      h("td", { class: "num" }, value(p.uninvolved, p.unit, p.unit === "s" ? 2 : 1)),
      h("td", { class: "num" }, typeof p.lsi_pct === "number" ? num(p.lsi_pct, 1) : "—")))),
    h("caption", { class: "caption" }, t("knees.lsi_caption")));
}

async function drawKnees(el, angle, knees) {
  const Plotly = await loadPlotly();
  const data = Object.entries(knees).sort().map(([side, k]) => {
    const mean = ((k.curves || {})[angle] || {}).mean || [];
    return { x: mean.map((_, i) => (mean.length > 1 ? (100 * i) / (mean.length - 1) : 0)), y: mean, mode: "lines",
      name: label("side", side), line: { color: SIDE_COLOURS[side], width: 2, dash: side === "right" ? "dash" : "solid" },
      hovertemplate: `%{x:.0f} %: %{y:.1f}°<extra>${label("side", side)}</extra>` };
  });
  const layout = { title: { text: label("angle", angle), font: { size: 15 }, x: 0, xanchor: "left" }, height: 280,
    margin: { l: 55, r: 15, t: 45, b: 45 }, separators: lang() === "en" ? ".," : ",.",
    xaxis: { range: [0, 100], title: { text: t("results.cycle_pct") } }, yaxis: { title: { text: "°" } },
    legend: { orientation: "h", y: 1.15, x: 1, xanchor: "right" }, paper_bgcolor: "rgba(0,0,0,0)", plot_bgcolor: "#fff" };
  await Plotly.newPlot(el, data, layout, { displaylogo: false, responsive: true });
}

/** Compare this session's analysis with another session of the patient (the other one as "a" when it is earlier). */
function compareSection(session, analysis) {
  const select = h("select", { id: "compare-with", name: "compare" }, h("option", { value: "" }, t("compare.choose")));
  const out = h("div", { id: "compare-out" });
  (async () => {
    try {
      const sessions = await api("GET", `/patients/${session.patient_id}/sessions`);
      sessions.filter((s) => s.id !== session.id && s.status === "done").forEach((s) =>
        select.append(h("option", { value: String(s.id), "data-date": s.date },
          t("compare.option", { id: s.id, date: date(s.date) }))));
    } catch (err) {
      out.append(alertBox(errorText(err)));
    }
  })();
  select.addEventListener("change", async () => {
    clear(out);
    if (!select.value) return;
    const other = Number(select.value);
    const otherDate = select.selectedOptions[0].dataset.date;
    const earlier = otherDate < session.date || (otherDate === session.date && other < session.id);
    const [a, b] = earlier ? [other, session.id] : [session.id, other];
    const query = earlier ? { a, b, b_analysis: analysis.id } : { a, b, a_analysis: analysis.id };
    try {
      out.append(compareTable(await api("GET", `/patients/${session.patient_id}/compare`, { query })));
    } catch (err) {
      out.append(alertBox(errorText(err)));
    }
  });
  return h("section", { class: "card compare", "aria-labelledby": "h-compare" },
    h("h2", { id: "h-compare" }, t("compare.title")), h("p", { class: "hint" }, t("compare.hint")),
    h("label", { for: "compare-with" }, t("compare.with")), select, out);
}

function compareLabel(key) {
  const [group, name, stat] = key.split(".");
  if (group === "rom_deg") return `${label("angle", name)} · ${t(`results.rom_${stat}`)}`;
  if (group === "phases") return `${label("phase", name)} (${t("results.cycle_share")})`;
  if (group === "symmetry") return `${t("knees.lsi")} · ${t(`knees.param.${name}`)}`;
  return t(`compare.gait.${key.split(".")[2]}`);
}

function compareTable(c) {
  const side = (x) => `#${x.session_id} · ${date(x.date)} · ${label("filter", x.filter)} · ${x.pipeline_version} · `
    + `${label("angle_convention", x.angle_method)} · ${label("calibration", x.calibration)}`;
  const unit = (u) => (u === "deg" ? "°" : ` ${t(`knees.unit.${u}`)}`);
  const cell = (x, u) => (typeof x === "number" ? `${num(x, u === "s" ? 2 : 1)}${unit(u)}` : "—");
  const change = (x, u) => (typeof x === "number" ? `${x > 0 ? "+" : ""}${num(x, u === "s" ? 2 : 1)}${unit(u)}` : "—");
  const notice = c.comparable ? [] : [h("div", { class: "notice warning", id: "compare-mismatch", role: "status" },
    t("compare.mismatch", { what: c.mismatch.map((m) => t(`compare.what.${m}`)).join(", ") }))];
  return h("div", {}, ...notice,
    h("table", { class: "data", id: "compare-table" },
      h("thead", {}, h("tr", {}, h("th", { scope: "col" }, t("knees.parameter")),
        h("th", { scope: "col", class: "num" }, side(c.a)), h("th", { scope: "col", class: "num" }, side(c.b)),
        h("th", { scope: "col", class: "num" }, t("compare.change")))),
      h("tbody", {}, c.rows.map((row) => h("tr", {}, h("th", { scope: "row" }, compareLabel(row.key)),
        h("td", { class: "num" }, cell(row.a, row.unit)), h("td", { class: "num" }, cell(row.b, row.unit)),
        h("td", { class: "num" }, change(row.change, row.unit)))))));
}

function romTable(r) {
  const rom = r.rom_deg || {};
  const stats = ["range", "max", "min"];
  return h("table", { class: "data", id: "rom-table" },
    h("thead", {}, h("tr", {}, h("th", { scope: "col" }, t("results.angle")),
      stats.map((s) => h("th", { scope: "col", class: "num" }, `${t(`results.rom_${s}`)} (°)`)))),
    h("tbody", {}, ANGLES.map((a) => h("tr", {}, h("th", { scope: "row" }, label("angle", a)),
      stats.map((s) => h("td", { class: "num" }, meanSd((rom[a] || {})[s])))))),
    h("caption", { class: "caption" }, t("results.mean_sd_caption")));
}

function phaseTable(r) {
  const phases = r.phases || {};
  return h("table", { class: "data", id: "phase-table" },
    h("thead", {}, h("tr", {}, h("th", { scope: "col" }, t("results.phase")),
      h("th", { scope: "col", class: "num" }, t("results.duration_s")),
      h("th", { scope: "col", class: "num" }, t("results.cycle_share")))),
    h("tbody", {}, Object.entries(phases).map(([name, p]) => h("tr", {},
      h("th", { scope: "row" }, label("phase", name)),
      h("td", { class: "num" }, meanSd(p, 2, "mean_s", "sd_s")),
      h("td", { class: "num" }, meanSd(p, 1, "mean_pct", "sd_pct"))))),
    h("caption", { class: "caption" }, t("results.mean_sd_caption")));
}

/** The task's reference (results.json `reference`): source, population, and per parameter value, band, flag. */
function referenceSection(ref) {
  const unit = { deg: "°", pct: " %", s: " s" };
  const rows = Object.entries(ref.parameters || {}).map(([name, p]) => {
    const d = p.unit === "s" ? 2 : 1;
    const band = p.low !== null && p.high !== null ? `${num(p.low, d)}–${num(p.high, d)}${unit[p.unit] || ""}`
      : `${num(p.mean, d)}${unit[p.unit] || ""}`;
    return h("tr", { class: p.within_band === false ? "outside" : null },
      h("th", { scope: "row" }, label("ref_param", name)),
      h("td", { class: "num" }, `${num(p.value, d)}${unit[p.unit] || ""}`), h("td", { class: "num" }, band),
      h("td", {}, p.interpretation ? t(`results.ref_flag_${p.interpretation}`) : "—"));
  });
  const text = (field) => { const key = `ref.${ref.id}.${field}`; const s = t(key); return s === key ? ref[field] : s; };
  return h("section", { class: "card", "aria-labelledby": "h-reference", id: "reference" },
    h("h2", { id: "h-reference" }, t("results.reference")),
    h("p", { class: "hint" }, `${t(`results.ref_kind_${ref.kind}`)}: ${ref.source}. ${text("population")}; ${text("conditions")}.`),
    h("table", { class: "data", id: "reference-table" },
      h("thead", {}, h("tr", {}, h("th", { scope: "col" }, t("results.ref_parameter")),
        h("th", { scope: "col", class: "num" }, t("results.ref_value")),
        h("th", { scope: "col", class: "num" }, t("results.ref_band")), h("th", { scope: "col" }, t("results.ref_flag")))),
      h("tbody", {}, rows)),
    h("p", { class: "caption" }, text("transcription")));
}

function qualitySection(r, translated) {
  // the server's list when it answered: it sorts clinical warnings from technical notes by one rule (reports.
  // warning_text.is_technical), also in a results.json written before the two lists were kept apart, whose
  // quality.warnings still holds the notes (matching the two lists by position fell back to English there)
  const served = Array.isArray(translated);
  const warnings = served ? translated.filter((x) => !x.technical) : (((r.quality || {}).warnings) || []);
  const texts = served ? warnings : [];
  // the pipeline's rejections; the clinician's exclusions are in the cycles card (cycles.js)
  const rejected = (((r.cycles || {}).rejected) || []).filter((c) => c.reason !== "excluded_by_clinician");
  const items = [
    // in the reader's language (GET .../warnings renders each from its code and params, as the reports do, the
    // knee of a two-knee session first: reports.warning_text); the English message when that answer is missing,
    // with the knee named (params.knee; app.pipeline.results.knees_warnings)
    ...warnings.map((w, i) => h("li", { class: "warning", "data-code": typeof w === "string" ? null : w.code },
      typeof w === "string" ? w : (((texts[i] || {}).message || {})[lang()]
        || `${(w.params || {}).knee ? t(`results.warning_knee.${w.params.knee}`) : ""}${w.message || w.code || ""}`))),
    ...rejected.map((c) => h("li", { class: "warning" }, t("results.rejected_cycle", {
      n: Number.isInteger(c.index) ? c.index + 1 : "?", reason: label("reason", c.reason) }), c.message && lang() === "en" ? ` — ${c.message}` : "")),   // English detail
  ];
  return h("section", { class: "card quality", "aria-labelledby": "h-quality" },
    h("h2", { id: "h-quality" }, t("results.quality")),
    items.length ? h("ul", { class: "warnings", id: "warnings" }, items)
      : h("p", { class: "ok-line" }, t("results.no_warnings")),
    technicalNotes(r, translated), calibrationFacts(r), splitFacts(r));
}

/** Where one continuous recording per sensor was cut into the protocol's parts (results.json session.split). */
function splitFacts(r) {
  const split = (r.session || {}).split;
  if (!split) return null;
  const parts = ["mag_calibration", "standing", "lying", "task"];
  const span = (p) => (p ? t("results.split_span", { from: num(p[0], 1), to: num(p[1], 1) }) : "—");
  const rows = ["thigh", "shank"].filter((s) => split[s]).map((s) => h("tr", {},
    h("th", { scope: "row" }, label("segment", s), h("div", { class: "hint" }, split[s].file || "")),
    ...parts.map((p) => h("td", { class: "num" }, span((split[s].spans_s || {})[p])))));
  return h("details", { class: "split", open: true }, h("summary", {}, t("results.split")),
    h("table", { class: "data", id: "split-table" },
      h("thead", {}, h("tr", {}, h("th", { scope: "col" }, t("results.segment")),
        ...parts.map((p) => h("th", { scope: "col", class: "num" }, t(`recording.${p}`))))),
      h("tbody", {}, rows)),
    h("p", { class: "hint" }, t("results.split_hint")));
}

/** The calibration figures worth a glance: magnetometer field and coverage, posture angle, disturbance. */
function calibrationFacts(r) {
  const cal = r.calibration || {};
  const mag = cal.magnetometer || {};
  const seg = cal.segment || {};
  const disturbed = (r.quality || {}).magnetic_disturbance_fraction || {};
  const rows = ["thigh", "shank"].filter((s) => mag[s] || seg[s]).map((s) => {
    const q = (mag[s] && (mag[s].quality || mag[s])) || {};
    const field = q.field_ut ?? (mag[s] || {}).field_ut;
    const cover = q.coverage_fraction;
    const angle = (seg[s] || {}).angle_between_postures_deg;
    const dist = disturbed[s];
    return h("tr", {}, h("th", { scope: "row" }, label("segment", s)),
      h("td", { class: "num" }, field == null ? "—" : `${num(field, 1)} µT`),
      h("td", { class: "num" }, cover == null ? "—" : `${num(100 * cover, 0)} %`),
      h("td", { class: "num" }, angle == null ? "—" : `${num(angle, 1)}°`),
      h("td", { class: "num" }, dist == null ? "—" : `${num(100 * dist, 1)} %`));
  });
  if (!rows.length) return null;
  return h("details", { class: "calibration" }, h("summary", {}, t("results.calibration")),
    h("table", { class: "data" },
      h("thead", {}, h("tr", {}, [t("results.segment"), t("results.mag_field"), t("results.mag_coverage"),
        t("results.posture_angle"), t("results.mag_disturbance")].map((c, i) => h("th", { scope: "col", class: i ? "num" : null }, c)))),
      h("tbody", {}, rows)),
    h("p", { class: "hint" }, t("results.calibration_hint")));
}

/** The clinician's interpretation of this analysis (issue 17 §3): a draft text box, "sign" (the logged-in user,
 * locked from then on), then "amend" with a required reason; the amendment history keeps each earlier text.
 * GET/POST /sessions/{id}/interpretation, …/sign, …/amendments; the PDF and HTML reports print the signed text. */
function interpretationSection(session, analysis) {
  const base = `/sessions/${session.id}/interpretation`;
  const query = { analysis_id: analysis.id };
  const editable = canEdit() && !analysis.superseded_at;
  const status = h("p", { id: "interp-status", role: "status" });
  const text = h("textarea", { id: "interp-text", name: "interpretation", rows: "6", maxlength: "20000",
    "aria-describedby": "interp-status" });
  const reason = h("input", { id: "interp-reason", name: "reason", type: "text", maxlength: "2000" });
  const reasonField = h("div", { class: "field", id: "interp-reason-field", hidden: true },
    h("label", { for: "interp-reason" }, t("interp.reason")), reason);
  const save = h("button", { type: "button", class: "secondary", id: "interp-save" }, t("interp.save"));
  const sign = h("button", { type: "button", class: "primary", id: "interp-sign" }, t("interp.sign"));
  const amend = h("button", { type: "button", class: "secondary", id: "interp-amend" }, t("interp.amend"));
  const amendSave = h("button", { type: "button", class: "primary", id: "interp-amend-save", hidden: true },
    t("interp.amend_save"));
  const out = h("div", { id: "interp-message" });
  const history = h("ol", { id: "interp-history", class: "history" });
  const historyBox = h("div", { id: "interp-history-box", hidden: true }, h("h3", {}, t("interp.history")), history);

  // hidden and display together: the style sheet gives buttons a display that would override [hidden]
  const shown = (el, on) => { el.hidden = !on; el.style.display = on ? "" : "none"; };
  let current = "";  // the text as the server last answered it: what a signature or an amendment refers to
  const show = (it) => {
    clear(out);
    text.value = it.text || "";
    current = it.text || "";
    const signed = it.status === "signed";
    status.textContent = signed
      ? t("interp.signed_by", { name: it.signed_by, role: label("role", it.signed_role), when: dateTime(it.signed_at) })
        + (it.amended ? ` · ${t("interp.amended")}` : "")
      : t(it.status === "draft" ? "interp.draft" : "interp.none");
    text.readOnly = signed || !editable;
    shown(save, !signed && editable);
    shown(sign, !signed && editable);
    shown(amend, signed && editable);
    shown(amendSave, false);
    shown(reasonField, false);
    reason.value = "";
    clear(history).append(...(it.amendments || []).map((a) => h("li", {},
      h("p", {}, t("interp.amendment_by", { name: a.by, role: label("role", a.role), when: dateTime(a.at) })),
      h("p", {}, h("strong", {}, `${t("interp.reason")}: `), a.reason),
      h("p", { class: "hint" }, h("strong", {}, `${t("interp.previous")}: `), a.previous_text))));
    shown(historyBox, (it.amendments || []).length > 0);
  };
  const act = async (method, path, json) => {
    try {
      show(await api(method, path, { json, query: method === "GET" ? query : undefined }));
      return true;
    } catch (err) {
      clear(out).append(alertBox(errorText(err)));
      return false;
    }
  };
  save.addEventListener("click", async () => {
    if (await act("POST", base, { text: text.value, analysis_id: analysis.id })) {
      out.append(h("p", { class: "notice", role: "status" }, t("interp.saved")));
    }
  });
  sign.addEventListener("click", async () => {
    if (!text.value.trim()) { clear(out).append(alertBox(t("interp.empty"))); return; }
    if (!window.confirm(t("interp.sign_confirm"))) return;
    // the text on screen is what is signed: saved first, then signed naming that text (409, nothing signed, if
    // someone else saved another text in between)
    if (await act("POST", base, { text: text.value, analysis_id: analysis.id })) {
      await act("POST", `${base}/sign`, { text: current, analysis_id: analysis.id });
    }
  });
  amend.addEventListener("click", () => {
    text.readOnly = false;
    shown(reasonField, true);
    shown(amendSave, true);
    shown(amend, false);
    text.focus();
  });
  amendSave.addEventListener("click", async () => {
    if (!reason.value.trim()) { clear(out).append(alertBox(t("interp.reason_needed"))); reason.focus(); return; }
    await act("POST", `${base}/amendments`, { text: text.value, reason: reason.value, expected_text: current,
      analysis_id: analysis.id });
  });
  act("GET", base);
  return h("section", { class: "card interpretation", id: "interpretation", "aria-labelledby": "h-interp" },
    h("h2", { id: "h-interp" }, t("interp.title")), h("p", { class: "hint" }, t("interp.hint")), status,
    h("div", { class: "field" }, h("label", { for: "interp-text" }, t("interp.text")), text), reasonField,
    h("div", { class: "actions wrap" }, save, sign, amend, amendSave), out, historyBox);
}

function downloadsSection(sessionId, analysisId) {
  const link = (path, query, text, name) => h("a", { href: apiUrl(`/sessions/${sessionId}/${path}`, { ...query, analysis_id: analysisId }),
    class: "button-link secondary", download: name || true }, text);
  // no name of our own: the server's (the patient's record number and the recordings' date) is kept
  const pdfs = LANGUAGES.map((code) => link("report.pdf", { lang: code }, t("results.pdf_lang", { lang: t(`lang.${code}`) })));
  const current = pdfs.splice(LANGUAGES.indexOf(lang()), 1)[0];
  current.classList.replace("secondary", "primary");
  return h("section", { class: "card downloads", "aria-labelledby": "h-downloads" },
    h("h2", { id: "h-downloads" }, t("results.downloads")),
    h("div", { class: "actions wrap" }, current, ...pdfs,
      link("angles.xlsx", {}, t("results.angles_xlsx")),
      link("quaternions.xlsx", {}, t("results.quaternions_xlsx")),
      h("a", { href: apiUrl(`/sessions/${sessionId}/report.html`, { analysis_id: analysisId, lang: lang() }), class: "button-link secondary",
        target: "_blank", rel: "noopener" }, t("results.report_html"))));
}
