// Plotly charts of the ChakaMo UI: mean ± SD curves over the cycle, and the ROM trend over sessions.
//
// plotly.js comes from the app (GET /vendor/plotly.min.js, the copy inside the installed plotly package):
// no CDN, the clinic may be offline.  It is loaded on first use (3.5 MB: the login page does not need it).
// Colours are the reports' (reports/html.py) so the web page, the HTML report and the PDF agree.
// Numbers use a decimal comma in es/pt (layout.separators).

import { t, lang } from "./i18n.js";
import { label } from "./dom.js";

export const ANGLES = ["flexion", "adduction", "internal_rotation"];
export const ANGLE_COLOURS = { flexion: "#1f77b4", adduction: "#ff7f0e", internal_rotation: "#2ca02c" };
const BANDS = { flexion: "rgba(31,119,180,0.2)", adduction: "rgba(255,127,14,0.2)",
  internal_rotation: "rgba(44,160,44,0.2)" };
const CONFIG = { displaylogo: false, responsive: true, modeBarButtonsToRemove: ["select2d", "lasso2d"] };

let plotlyPromise = null;

/** window.Plotly, loading /vendor/plotly.min.js once. */
export function loadPlotly() {
  if (window.Plotly) return Promise.resolve(window.Plotly);
  if (!plotlyPromise) {
    plotlyPromise = new Promise((resolve, reject) => {
      const script = document.createElement("script");
      script.src = "/vendor/plotly.min.js";
      script.addEventListener("load", () => resolve(window.Plotly));
      script.addEventListener("error", () => {
        plotlyPromise = null;
        reject(new Error(t("error.plotly")));
      });
      document.head.append(script);
    });
  }
  return plotlyPromise;
}

function separators() {
  return lang() === "en" ? ".," : ",.";
}

/** Phase spans on the normalised cycle: cumulative mean percentages → [[name, start %, end %]]. */
export function phaseSpans(phases) {
  const out = [];
  let acc = 0;
  for (const [name, p] of Object.entries(phases || {})) {
    if (!p || typeof p.mean_pct !== "number" || !Number.isFinite(p.mean_pct)) continue;
    out.push([name, acc, acc + p.mean_pct]);
    acc += p.mean_pct;
  }
  return out;
}

/** The reference's key ranges of the mean flexion (results.json `reference.keypoints`) as open boxes. */
export const REFERENCE_COLOUR = "#d67800";
export function referenceShapes(keypoints) {
  return (keypoints || []).filter((k) => Array.isArray(k.pct) && Array.isArray(k.deg)).map((k) => ({
    type: "rect", xref: "x", yref: "y", x0: k.pct[0], x1: k.pct[1], y0: k.deg[0], y1: k.deg[1],
    line: { color: REFERENCE_COLOUR, width: 2 } }));
}

/**
 * Draw one angle's mean ± SD over 0–100 % of the cycle into `el` (results.json `curves[angle]`); `keypoints`
 * (results.json `reference.keypoints`, flexion only) adds the reference's key ranges.
 */
export async function drawCurve(el, angle, curve, phases, keypoints) {
  const Plotly = await loadPlotly();
  const mean = (curve && curve.mean) || [];
  const sd = (curve && curve.sd) || mean.map(() => null);
  const pct = mean.map((_, i) => (mean.length > 1 ? (100 * i) / (mean.length - 1) : 0));
  const add = (k) => mean.map((m, i) => (m === null || sd[i] === null ? null : m + k * sd[i]));
  const name = label("angle", angle);
  const data = [
    { x: pct, y: add(1), mode: "lines", line: { width: 0 }, hoverinfo: "skip", showlegend: false },
    { x: pct, y: add(-1), mode: "lines", line: { width: 0 }, fill: "tonexty", fillcolor: BANDS[angle],
      hoverinfo: "skip", showlegend: false },
    { x: pct, y: mean, mode: "lines", name, line: { color: ANGLE_COLOURS[angle], width: 2 }, customdata: sd,
      hovertemplate: `%{x:.0f} %: %{y:.1f} ± %{customdata:.1f}°<extra></extra>`, showlegend: false },
  ];
  const shapes = referenceShapes(keypoints);
  const annotations = [];
  if (shapes.length) {
    annotations.push({ x: 1, y: 1.12, xref: "paper", yref: "paper", xanchor: "right", showarrow: false,
      text: `<span style="color:${REFERENCE_COLOUR}">□</span> ${t("results.reference_band")}`, font: { size: 11 } });
  }
  phaseSpans(phases).forEach(([phase, p0, p1], k) => {
    if (k > 0) {
      shapes.push({ type: "line", xref: "x", yref: "paper", x0: p0, x1: p0, y0: 0, y1: 1,
        line: { color: "#5c677d", width: 1, dash: "dash" } });
    }
    annotations.push({ x: (p0 + p1) / 2, y: 1, xref: "x", yref: "paper", yanchor: "bottom", showarrow: false,
      text: label("phase", phase), font: { size: 11, color: "#5c677d" } });
  });
  const layout = {
    title: { text: name, font: { size: 15 }, x: 0, xanchor: "left" },
    height: 300, margin: { l: 55, r: 15, t: 60, b: 45 }, separators: separators(),
    xaxis: { range: [0, 100], title: { text: t("results.cycle_pct") }, zeroline: false },
    yaxis: { title: { text: t("results.degrees") } },
    shapes, annotations, hovermode: "closest", paper_bgcolor: "rgba(0,0,0,0)", plot_bgcolor: "#fff",
  };
  await Plotly.newPlot(el, data, layout, CONFIG);
}

/**
 * Draw the ROM trend: for each angle the range of motion (mean ± SD over accepted cycles) of each processed
 * session, oldest first (GET /patients/{id}/trend `points`).
 */
export async function drawTrend(el, points) {
  const Plotly = await loadPlotly();
  const x = points.map((p) => `${p.date || ""} · #${p.session_id}`);
  const data = ANGLES.map((angle) => {
    const range = points.map((p) => (p.rom_deg && p.rom_deg[angle] && p.rom_deg[angle].range) || {});
    return {
      x, y: range.map((r) => (typeof r.mean === "number" ? r.mean : null)), type: "scatter", mode: "lines+markers",
      name: label("angle", angle), line: { color: ANGLE_COLOURS[angle], width: 2 }, marker: { size: 8 },
      error_y: { type: "data", array: range.map((r) => (typeof r.sd === "number" ? r.sd : 0)), visible: true,
        color: ANGLE_COLOURS[angle], thickness: 1 },
      customdata: points.map((p) => label("filter", p.filter)),
      hovertemplate: `%{y:.1f}° (%{customdata})<extra>${label("angle", angle)}</extra>`,
    };
  });
  const layout = {
    height: 340, margin: { l: 55, r: 15, t: 20, b: 60 }, separators: separators(),
    xaxis: { type: "category", title: { text: t("patient.trend_x") } },
    yaxis: { title: { text: t("patient.trend_y") }, rangemode: "tozero" },
    legend: { orientation: "h", y: -0.25 }, paper_bgcolor: "rgba(0,0,0,0)", plot_bgcolor: "#fff",
  };
  await Plotly.newPlot(el, data, layout, CONFIG);
}

/** Free a chart's listeners when its view goes away. */
export function purge(el) {
  if (window.Plotly && el) window.Plotly.purge(el);
}
