// Translations of the ChakaMo UI: es, en, pt.
//
// Every visible text comes from static/i18n/<lang>.json (flat "section.name" keys, "{name}" placeholders).
// The language is, in order: the user's stored choice (localStorage "chakamo.lang"), the first browser
// language among es/en/pt (navigator.languages, "pt-BR" → pt), else English.  English is loaded as well
// and used for a key missing in the chosen table; a key missing everywhere shows as the key itself (the
// test tests/app/web/test_browser_e2e.py checks the three tables have the same keys).

export const LANGUAGES = ["es", "en", "pt"];
const STORE_KEY = "chakamo.lang";

let current = "en";
const tables = {};

/** The language the UI shows ("es", "en" or "pt"). */
export function lang() {
  return current;
}

/** The language to start with: stored choice, else the browser's, else English. */
export function initialLanguage() {
  try {
    const stored = localStorage.getItem(STORE_KEY);
    if (LANGUAGES.includes(stored)) return stored;
  } catch (_) { /* storage disabled: fall through */ }
  for (const tag of navigator.languages || [navigator.language || "en"]) {
    const base = String(tag).toLowerCase().split("-")[0];
    if (LANGUAGES.includes(base)) return base;
  }
  return "en";
}

async function load(code) {
  if (!tables[code]) {
    const res = await fetch(`/static/i18n/${code}.json`, { credentials: "same-origin" });
    if (!res.ok) throw new Error(`translations ${code}: HTTP ${res.status}`);
    tables[code] = await res.json();
  }
  return tables[code];
}

/** Switch to `code` (loads its table), remember the choice when `remember`, set <html lang>. */
export async function setLanguage(code, { remember = true } = {}) {
  if (!LANGUAGES.includes(code)) throw new Error(`unknown language ${code}; use es, en or pt`);
  await Promise.all([load("en"), load(code)]);
  current = code;
  document.documentElement.lang = code;
  if (remember) {
    try { localStorage.setItem(STORE_KEY, code); } catch (_) { /* storage disabled */ }
  }
}

/** The text of `key` in the current language with `{name}` placeholders filled from `params`. */
export function t(key, params = {}) {
  const text = (tables[current] && tables[current][key]) ?? (tables.en && tables.en[key]) ?? key;
  return text.replace(/\{(\w+)\}/g, (whole, name) => (name in params ? String(params[name]) : whole));
}

/** Fill the static page: elements with data-i18n get their text, data-i18n-attr="attr:key" an attribute. */
export function translateStatic(root = document) {
  for (const el of root.querySelectorAll("[data-i18n]")) el.textContent = t(el.dataset.i18n);
  for (const el of root.querySelectorAll("[data-i18n-attr]")) {
    const [attr, key] = el.dataset.i18nAttr.split(":");
    el.setAttribute(attr, t(key));
  }
}
