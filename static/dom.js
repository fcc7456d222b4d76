// DOM and formatting helpers of the ChakaMo UI.
//
// Decision: every element is built with document.createElement and every text goes in as a text node
// (h() appends strings with Node.append, which never parses HTML).  Patient names, notes and file names are
// user input: nothing in the UI assigns innerHTML, so no user text can become markup (XSS).
// Event handlers are attached with addEventListener (the `on…` keys of h()), never as HTML attributes.

import { t, lang } from "./i18n.js";

/**
 * Build an element: h("a", {href: "#/x", class: "link", onclick: fn}, "text", child, [more children]).
 * Attribute values null/undefined/false are skipped, true sets an empty attribute; `text` sets textContent;
 * `on<event>` keys add listeners; children are Nodes or strings (strings become text nodes).
 */
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === null || value === undefined || value === false) continue;
    if (key === "class") el.className = value;
    else if (key === "text") el.textContent = value;
    else if (key === "value" && "value" in el && tag !== "option" && tag !== "progress") el.value = value;
    else if (key.startsWith("on") && typeof value === "function") el.addEventListener(key.slice(2), value);
    else if (value === true) el.setAttribute(key, "");
    else el.setAttribute(key, String(value));
  }
  append(el, children);
  return el;
}

/** Append children (Nodes, strings, numbers, nested arrays; null/false skipped) to `el`. */
export function append(el, children) {
  for (const child of [children].flat(Infinity)) {
    if (child === null || child === undefined || child === false) continue;
    el.append(child instanceof Node ? child : String(child));
  }
  return el;
}

/** Remove every child of `el`. */
export function clear(el) {
  el.replaceChildren();
  return el;
}

let uid = 0;
/** A fresh element id with the given prefix (labels need ids). */
export function newId(prefix = "id") {
  uid += 1;
  return `${prefix}-${uid}`;
}

/** A labelled form field: returns [wrapper, control]. `control` is an element whose id is set here. */
export function field(labelText, control, hint) {
  const id = control.id || newId("f");
  control.id = id;
  const hintEl = hint ? h("small", { class: "hint", id: `${id}-hint` }, hint) : null;
  if (hintEl) control.setAttribute("aria-describedby", hintEl.id);
  return [h("div", { class: "field" }, h("label", { for: id }, labelText), control, hintEl), control];
}

/** An error/notice box; `role="alert"` makes screen readers announce it. */
export function alertBox(message, kind = "error") {
  return h("div", { class: `notice ${kind}`, role: kind === "error" ? "alert" : "status" }, message);
}

/** A button that opens (and closes again) the form `makeForm(close)` in `formArea`; aria-expanded follows. */
export function disclosure(text, formArea, makeForm, attrs = {}) {
  const button = h("button", { type: "button", "aria-expanded": "false", ...attrs }, text);
  const close = () => { button.setAttribute("aria-expanded", "false"); clear(formArea); };
  button.addEventListener("click", () => {
    const open = button.getAttribute("aria-expanded") === "true";
    close();
    if (!open) {
      button.setAttribute("aria-expanded", "true");
      formArea.append(makeForm(close));
    }
  });
  return button;
}

// ------------------------------------------------------------------------------------------ formatting
const MISSING = "—";

/** A number with `digits` decimals in the UI language (decimal comma in es/pt); "—" when missing. */
export function num(x, digits = 1) {
  if (x === null || x === undefined || Number.isNaN(Number(x)) || x === "") return MISSING;
  return new Intl.NumberFormat(lang(), { minimumFractionDigits: digits, maximumFractionDigits: digits })
    .format(Number(x));
}

/** "mean ± sd" of a results.json statistic object (only the mean when sd is missing). */
export function meanSd(stat, digits = 1, meanKey = "mean", sdKey = "sd") {
  if (!stat || stat[meanKey] === null || stat[meanKey] === undefined) return MISSING;
  const sd = stat[sdKey];
  return sd === null || sd === undefined ? num(stat[meanKey], digits) : `${num(stat[meanKey], digits)} ± ${num(sd, digits)}`;
}

/** A calendar date "YYYY-MM-DD" in the UI language (no time-zone shift). */
export function date(iso) {
  if (!iso) return MISSING;
  const m = /^(\d{4})-(\d{2})-(\d{2})/.exec(iso);
  if (!m) return String(iso);
  const d = new Date(Date.UTC(Number(m[1]), Number(m[2]) - 1, Number(m[3])));
  return new Intl.DateTimeFormat(lang(), { dateStyle: "medium", timeZone: "UTC" }).format(d);
}

/** An ISO 8601 timestamp in the UI language, local time. */
export function dateTime(iso) {
  if (!iso) return MISSING;
  const d = new Date(/[zZ]|[+-]\d\d:?\d\d$/.test(iso) ? iso : `${iso}Z`);
  if (Number.isNaN(d.getTime())) return String(iso);
  return new Intl.DateTimeFormat(lang(), { dateStyle: "medium", timeStyle: "short" }).format(d);
}

/** A byte count as "1.2 MB". */
export function bytes(n) {
  if (n === null || n === undefined) return MISSING;
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${num(n / 1024, 0)} kB`;
  return `${num(n / (1024 * 1024), 1)} MB`;
}

/** A translated label with a fallback to the raw value (e.g. a phase name unknown to this version). */
export function label(prefix, value) {
  if (value === null || value === undefined) return MISSING;
  const key = `${prefix}.${value}`;
  const text = t(key);
  return text === key ? String(value) : text;
}

/** The sentence to show for a failed call: the server's `detail`, or a translated network error. */
export function errorText(err) {
  if (err && err.status === 0) return t("error.network");
  return (err && (err.detail || err.message)) || t("error.unknown");
}

/**
 * A decimal number typed by a person, whatever the UI language: "165,5" and "165.5" are both 165.5 (one comma or
 * one point is the decimal mark).  null for an empty field, NaN for anything else, which the caller says in the UI
 * language: "1.65.5", "abc", inner spaces ("7 5": 75 or a slip?), and a mark followed by exactly three digits
 * after a non-zero whole part ("1,655", "1.655"): an English reader means 1655 (a thousands comma), a Spanish or
 * Portuguese one 1655 as well (a thousands point) or 1.655 — which, cannot be known, and 1000 times off is not a
 * slip to guess at.  "0,175" (a step in metres) is not ambiguous and is read.
 */
export function parseDecimal(text) {
  const v = String(text ?? "").trim();
  if (v === "") return null;
  if (!/^[+-]?(\d+([.,]\d*)?|[.,]\d+)$/.test(v) || /^[+-]?0*[1-9]\d*[.,]\d{3}$/.test(v)) return Number.NaN;
  return Number(v.replace(",", "."));
}

/** `x` as a person types it in the UI language, all its decimals kept and no grouping ("165,5" in es/pt). */
export function decimalText(x) {
  if (x === null || x === undefined || x === "") return "";
  return new Intl.NumberFormat(lang(), { maximumFractionDigits: 6, useGrouping: false }).format(Number(x));
}
