// The option lists of GET /api/v1/options (app/choices.py on the server: filters, tasks, languages,
// calibrations, angle conventions, sides).  Every menu of the UI is built from this one answer, fetched once
// per page load, so a filter or task added on the server appears here without a change to the UI.

import { api } from "./api.js";
import { h } from "./dom.js";
import { t } from "./i18n.js";

let pending = null;

/** The option lists (a promise, cached; a failed fetch is retried on the next call, and `fresh` asks again). */
export function options(fresh = false) {
  if (!pending || fresh) pending = api("GET", "/options").catch((err) => { pending = null; throw err; });
  return pending;
}

/** An option's text: the UI's translation `${kind}.${name}` when it has one, else the server's label. */
export function optionLabel(kind, option) {
  const key = `${kind}.${option.name}`;
  const text = t(key);
  return text === key ? option.label : text;
}

/** Fill `select` with `items` (the server's option list); `selected` (a name) or the list's default chosen. */
export function fillSelect(select, kind, items, selected = null) {
  const chosen = items.some((o) => o.name === selected) ? selected : (items.find((o) => o.default) || items[0]).name;
  select.replaceChildren(...items.map((o) => h("option", { value: o.name, selected: o.name === chosen },
    optionLabel(kind, o))));
  return select;
}
