// The results page's per-cycle inspection (issue 17 §4): every detected cycle of each knee — its normalised flexion
// curve (results.json cycles.per_cycle[].flexion_deg) and numbers, accepted, rejected by the pipeline (with its
// reason) or excluded by the clinician (who, when, why: cycles.excluded) — and the clinician's choice of cycles.
//
// Excluding or including cycles asks for the analysis again (POST /sessions/{id}/process with the analysis' id,
// `based_on_analysis_id`, whose options the server copies, plus `exclude_cycles`: the whole set, so a cycle left
// unticked is included again).  The server records who excluded which cycle and why on the new analysis, which
// supersedes the earlier ones (kept, for the record; the audit log names the request).  The page follows the job
// (GET /jobs/{id}) and opens the new analysis when it is done.  Cycles the pipeline could not measure
// (incomplete, a turn...) cannot be chosen: they have no curve to include.
//
// Also here: the technical notes (how the files were read: stream tails cut, clock drift...), kept apart from the
// clinical warnings in results.json quality.technical_notes and shown folded away.

import { api } from "../api.js";
import { h, clear, alertBox, errorText, num, label } from "../dom.js";
import { t, lang } from "../i18n.js";
import { loadPlotly, purge } from "../charts.js";
import { canEdit, navigate } from "../app.js";

const EXCLUDED = "excluded_by_clinician";
// a cycle the clinician may exclude or include: accepted, excluded, or left out by the RMSE rejection
const CHOOSABLE = (c) => c.accepted || c.reason === EXCLUDED || c.reason === "rmse";
const COLOURS = { accepted: "#1f77b4", rejected: "#c62828", excluded: "#8a8f98" };

/** The cycles card: one block per knee (two in a session of both knees), and the reprocess action. */
export function cyclesSection(session, analysis, r) {
  const knees = r.knees && Object.keys(r.knees).length === 2
    ? Object.entries(r.knees).sort().map(([side, k]) => [side, k]) : [[null, r]];
  const job = (session.jobs || []).find((j) => j.id === analysis.job_id) || {};
  const editable = canEdit() && !analysis.superseded_at;
  const blocks = knees.map(([side, k]) => kneeBlock(side, k, editable));
  const status = h("div", { id: "cycles-status", role: "status", "aria-live": "polite" });
  const button = h("button", { type: "button", class: "primary", id: "cycles-reprocess", disabled: true },
    t("cycles.reprocess"));
  const chosen = () => blocks.flatMap((b) => b.chosen());
  const changed = () => blocks.some((b) => b.changed());
  blocks.forEach((b) => b.onChange(() => { button.disabled = !changed(); }));
  button.addEventListener("click", () => reprocess(session, analysis, job, chosen(), button, status));
  const section = h("section", { class: "card cycles", id: "cycles", "aria-labelledby": "h-cycles" },
    h("h2", { id: "h-cycles" }, t("cycles.title")), h("p", { class: "hint" }, t("cycles.hint")),
    ...blocks.map((b) => b.el),
    editable ? h("div", { class: "actions" }, button) : h("p", { class: "hint", id: "cycles-locked" },
      t(analysis.superseded_at ? "cycles.superseded" : "cycles.read_only")),
    status);
  // drawn when scrolled near: plotly shares the page's one thread with the 3D view's boot (scene.js)
  const observer = new IntersectionObserver((entries) => entries.forEach((e) => {
    if (!e.isIntersecting) return;
    observer.unobserve(e.target);
    const b = blocks.find((x) => x.chart === e.target);
    b.draw().catch((err) => b.chart.replaceWith(alertBox(errorText(err))));
  }), { rootMargin: "200px" });
  blocks.forEach((b) => observer.observe(b.chart));
  return section;
}

function statusText(c, excluded) {
  if (c.accepted) return t("cycles.accepted");
  if (c.reason === EXCLUDED) {
    const e = excluded.get(c.index + 1) || {};
    return t("cycles.excluded", { by: e.by || "—", date: String(e.at || "").slice(0, 10) || "—",
      reason: e.reason || t("cycles.no_reason") });
  }
  return t("cycles.rejected", { reason: label("reason", c.reason) });
}

function kind(c) {
  return c.accepted ? "accepted" : c.reason === EXCLUDED ? "excluded" : "rejected";
}

/** One knee's cycles: the curves overlaid, and a table with a tick box and a reason per cycle (`editable`: the
 * user may change data and the analysis is the current one). */
function kneeBlock(side, k, editable) {
  const cycles = (k.cycles || {}).per_cycle || [];
  const excluded = new Map(((k.cycles || {}).excluded || []).map((e) => [e.cycle, e]));
  const suffix = side || "only";
  const chart = h("div", { class: "chart", id: `cycles-chart-${suffix}`, role: "img",
    "aria-label": t("cycles.curve_alt") });
  const listeners = [];
  const rows = cycles.map((c) => {
    const n = c.index + 1;
    const box = h("input", { type: "checkbox", id: `exclude-${suffix}-${n}`, "data-cycle": String(n),
      checked: c.reason === EXCLUDED, disabled: !CHOOSABLE(c) || !editable });
    const reason = h("input", { type: "text", id: `reason-${suffix}-${n}`, maxlength: "300", class: "reason",
      value: (excluded.get(n) || {}).reason || "", placeholder: t("cycles.reason_placeholder"),
      "aria-label": t("cycles.reason_for", { n }), disabled: !box.checked || !editable });
    box.addEventListener("change", () => { reason.disabled = !box.checked; listeners.forEach((f) => f()); });
    reason.addEventListener("input", () => listeners.forEach((f) => f()));
    const range = (((c.rom_deg || {}).flexion) || {}).range;
    const max = (((c.rom_deg || {}).flexion) || {}).max;
    const dur = typeof c.start_s === "number" && typeof c.end_s === "number" ? c.end_s - c.start_s : null;
    const row = h("tr", { class: `cycle ${kind(c)}`, "data-cycle": String(n) },
      h("th", { scope: "row" }, String(n)),
      h("td", { class: "status" }, statusText(c, excluded)),
      h("td", { class: "num" }, typeof range === "number" ? num(range, 1) : "—"),
      h("td", { class: "num" }, typeof max === "number" ? num(max, 1) : "—"),
      h("td", { class: "num" }, dur === null ? "—" : num(dur, 2)),
      h("td", { class: "center" }, h("label", { class: "visually-hidden", for: box.id }, t("cycles.exclude_n", { n })), box),
      h("td", {}, reason));
    return { c, n, box, reason, row };
  });
  const initial = JSON.stringify(rows.map((x) => [x.box.checked, x.reason.value]));
  const table = h("table", { class: "data", id: `cycles-table-${suffix}` },
    h("thead", {}, h("tr", {}, ["cycles.col_cycle", "cycles.col_status", "cycles.col_range", "cycles.col_max",
      "cycles.col_duration", "cycles.col_exclude", "cycles.col_reason"].map((key, i) =>
      h("th", { scope: "col", class: i >= 2 && i <= 4 ? "num" : null }, t(key))))),
    h("tbody", {}, rows.map((x) => x.row)));
  const el = h("div", { class: "knee-cycles", "data-knee": side || "" },
    side ? h("h3", {}, label("side", side)) : null, chart, h("div", { class: "table-scroll" }, table));

  async function draw() {
    const Plotly = await loadPlotly();
    const data = rows.filter((x) => Array.isArray(x.c.flexion_deg)).map((x) => {
      const y = x.c.flexion_deg;
      const k2 = kind(x.c);
      return { x: y.map((_, i) => (100 * i) / (y.length - 1)), y, mode: "lines", name: t("cycles.legend", { n: x.n }),
        line: { color: COLOURS[k2], width: k2 === "accepted" ? 1.5 : 1.2, dash: k2 === "accepted" ? "solid" : k2 === "excluded" ? "dash" : "dot" },
        hovertemplate: `${t("cycles.legend", { n: x.n })} · %{x:.0f} %: %{y:.1f}°<extra></extra>` };
    });
    const layout = { title: { text: label("angle", "flexion"), font: { size: 15 }, x: 0, xanchor: "left" }, height: 300,
      margin: { l: 55, r: 15, t: 45, b: 45 }, separators: lang() === "en" ? ".," : ",.", showlegend: true,
      xaxis: { range: [0, 100], title: { text: t("results.cycle_pct") } }, yaxis: { title: { text: "°" } },
      paper_bgcolor: "rgba(0,0,0,0)", plot_bgcolor: "#fff" };
    await Plotly.newPlot(chart, data, layout, { displaylogo: false, responsive: true });
    const observer = new MutationObserver(() => { if (!chart.isConnected) { purge(chart); observer.disconnect(); } });
    observer.observe(document.getElementById("main"), { childList: true });
  }

  return {
    el, chart, draw,
    onChange: (f) => listeners.push(f),
    changed: () => JSON.stringify(rows.map((x) => [x.box.checked, x.reason.value])) !== initial,
    chosen: () => rows.filter((x) => x.box.checked && !x.box.disabled)
      .map((x) => ({ cycle: x.n, knee: side, reason: x.reason.value.trim() })),
  };
}

async function reprocess(session, analysis, job, exclude, button, status) {
  button.disabled = true;
  clear(status).append(h("p", { class: "loading" }, t("cycles.reprocessing")));
  // the server copies the analysis' own options (filter, heading, side, involved knee, calibration, angle
  // convention) and refuses (409) when it is no longer the session's current analysis
  const body = { lang: job.lang || lang(), based_on_analysis_id: analysis.id, exclude_cycles: exclude };
  let jobId;
  try {
    jobId = (await api("POST", `/sessions/${session.id}/process`, { json: body })).job_id;
  } catch (err) {
    clear(status).append(alertBox(errorText(err)));
    button.disabled = false;
    return;
  }
  await followJob(session.id, jobId, status, t("cycles.reprocessing"), () => { button.disabled = false; });
}

/** Follow job `jobId` in `status` (a progress bar under `text`) and open its analysis when it is done; on failure
 * show its message in the reader's language and call `failed()`.  Stops when the page is left. */
export async function followJob(sessionId, jobId, status, text, failed) {
  const progress = h("progress", { max: "1", value: "0", class: "job-progress" });
  clear(status).append(h("p", {}, text), progress);
  for (;;) {
    await new Promise((r) => setTimeout(r, 400));
    if (!status.isConnected) return;               // the page was left: stop following
    let j;
    try {
      j = await api("GET", `/jobs/${jobId}`);
    } catch (err) {
      clear(status).append(alertBox(errorText(err)));
      return;
    }
    progress.value = j.progress || 0;
    if (j.status === "done") {
      navigate(`#/sessions/${sessionId}?analysis_id=${j.analysis_id}`);
      return;
    }
    if (j.status === "failed") {
      clear(status).append(alertBox((j.error_message || {})[lang()] || j.error || t("cycles.failed")));
      failed();
      return;
    }
  }
}

/** The technical notes on reading the files, folded away; `texts` the server's translations (GET .../warnings). */
export function technicalNotes(r, texts) {
  // the server's classification when it answered (an older results.json kept the notes among the warnings)
  const notes = Array.isArray(texts) ? texts.filter((x) => x.technical) : (((r.quality || {}).technical_notes) || []);
  if (!notes.length) return null;
  const items = notes.map((w) => h("li", { "data-code": w.code }, ((w.message || {})[lang()]) || w.message || w.code));
  return h("details", { class: "technical-notes", id: "technical-notes" },
    h("summary", {}, t("results.technical_notes", { n: notes.length })),
    h("p", { class: "hint" }, t("results.technical_notes_hint")), h("ul", {}, items));
}
