// The clinic's administration, for admins only: #/admin/users (accounts: create, change role, disable / enable,
// unlock), #/admin/tokens (API tokens of hospital systems: create, rotate, revoke) and #/admin/audit (the audit
// log, newest first, with filters and paging).
//
// Decisions:
// - Everything goes through the admin API (app/web/api/users.py, tokens.py, audit.py); the server refuses others
//   (403) and says why in the UI's language, shown as it comes.  An admin's own row cannot be demoted or disabled
//   (the server refuses it too): its controls are not offered.
// - A new or rotated token is shown once, in a read-only field with a copy button, and never again: only its
//   sha256 is stored.  Revoking asks for confirmation in the modal dialog of records.js.
// - The audit log pages back with `before_id` (the smallest id of the page shown), as the API does; the filters
//   (action, user, patient, since) restart at the newest page.  The actions and token scopes come from
//   GET /options, so a new action appears here without a change to the UI.

import { api } from "../api.js";
import { h, clear, field, alertBox, errorText, dateTime, label, parseDecimal, num, disclosure } from "../dom.js";
import { t } from "../i18n.js";
import { options } from "../options.js";
import { currentUser } from "../app.js";
import { confirmErase } from "./records.js";

const AUDIT_PAGE = 50;
const PAGES = ["users", "tokens", "audit"];

/** The admin page `page` ("users", "tokens" or "audit"). */
export function adminView(page) {
  const section = h("section", { class: "view admin" });
  const user = currentUser();
  if (!user || user.role !== "admin") {
    section.append(h("h1", {}, t("admin.title")), alertBox(t("admin.only_admins")));
    return section;
  }
  const tabs = h("nav", { class: "tabs", "aria-label": t("admin.title") }, PAGES.map((p) =>
    h("a", { href: `#/admin/${p}`, "aria-current": p === page ? "page" : null }, t(`admin.tab_${p}`))));
  section.append(h("h1", {}, t(`admin.title_${page}`)), tabs);
  if (page === "users") section.append(...usersPage());
  else if (page === "tokens") section.append(...tokensPage());
  else section.append(...auditPage());
  return section;
}

/** A select of the roles (GET /options `roles`, app/choices.py USER_ROLES), `selected` chosen. */
function roleSelect(name, selected) {
  const select = h("select", { name }, h("option", { value: selected, selected: true }, label("role", selected)));
  options().then((opts) => {
    clear(select).append(...(opts.roles || [selected]).map((r) =>
      h("option", { value: r, selected: r === selected }, label("role", r))));
  }).catch(() => {});   // the select keeps the current role; the page's other calls say what failed
  return select;
}

/** A token scope in words of the UI language: "Patients — read" for `patients:read`. */
export function scopeLabel(scope) {
  const [resource, action] = String(scope).split(":");
  return `${label("scope_resource", resource)} — ${label("scope_action", action)}`;
}

// ------------------------------------------------------------------------------------------------- users
function usersPage() {
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const listArea = h("div", { class: "table-scroll" });
  const formArea = h("div");
  const newButton = disclosure(t("admin.user_new"), formArea, (close) => newUserForm(close, load), { id: "new-user" });

  async function load(note) {   // (hoisted: the form above calls it after a creation)
    let users;
    try {
      users = await api("GET", "/users");
    } catch (err) {
      clear(listArea).append(alertBox(errorText(err)));
      return;
    }
    clear(message);
    if (note) message.append(alertBox(note, "info"));
    clear(listArea).append(usersTable(users, message, load));
  }
  load();
  return [h("div", { class: "actions wrap" }, newButton), formArea,
    h("div", { class: "card" }, message, listArea)];
}

function usersTable(users, message, reload) {
  const me = (currentUser() || {}).id;
  const act = async (fn, done, undo) => {
    clear(message);
    try {
      await fn();
      reload(done);
    } catch (err) {
      if (undo) undo();   // a refused change leaves the control as it is stored
      message.append(alertBox(errorText(err)));
    }
  };
  const rows = users.map((u) => {
    const self = u.id === me;
    const role = roleSelect(`role-${u.id}`, u.role);
    role.setAttribute("aria-label", t("admin.user_role_of", { name: u.name || u.email }));
    role.disabled = self;
    role.addEventListener("change", () => act(() => api("PATCH", `/users/${u.id}`, { json: { role: role.value } }),
      t("admin.user_changed", { name: u.name || u.email }), () => { role.value = u.role; }));
    const toggle = self ? null : h("button", { type: "button", class: u.active ? "danger small" : "secondary small",
      "data-action": u.active ? "disable" : "enable" }, u.active ? t("admin.user_disable") : t("admin.user_enable"));
    if (toggle) {
      toggle.addEventListener("click", () => act(() => api("PATCH", `/users/${u.id}`, { json: { active: !u.active } }),
        t("admin.user_changed", { name: u.name || u.email })));
    }
    const unlock = h("button", { type: "button", class: "secondary small", "data-action": "unlock" }, t("admin.user_unlock"));
    unlock.addEventListener("click", () => act(() => api("POST", `/users/${u.id}/unlock`),
      t("admin.user_unlocked", { name: u.name || u.email })));
    return h("tr", { "data-user-id": String(u.id), "data-active": String(u.active) },
      h("td", {}, u.name || "—", self ? h("span", { class: "tag" }, t("admin.you")) : null),
      h("td", { class: "break" }, u.email),
      h("td", {}, role),
      h("td", {}, h("span", { class: `badge ${u.active ? "status-done" : "status-failed"}` },
        u.active ? t("admin.user_active") : t("admin.user_inactive"))),
      h("td", {}, h("div", { class: "row-actions" }, toggle, unlock)));
  });
  return h("table", { class: "data", id: "users-table" },
    h("thead", {}, h("tr", {}, [t("admin.user_name"), t("login.email"), t("admin.user_role"), t("admin.user_state"), ""]
      .map((c) => h("th", { scope: "col" }, c)))),
    h("tbody", {}, rows));
}

function newUserForm(onClose, reload) {
  const f = {
    email: h("input", { type: "email", name: "email", required: true, autocomplete: "off", maxlength: 320 }),
    name: h("input", { name: "name", autocomplete: "off", maxlength: 200 }),
    role: roleSelect("role", "clinician"),
    password: h("input", { type: "password", name: "password", required: true, autocomplete: "new-password" }),
  };
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const submit = h("button", { type: "submit" }, t("admin.user_create"));
  const form = h("form", { class: "card form-grid", id: "new-user-form", "aria-label": t("admin.user_new") },
    h("h2", {}, t("admin.user_new")),
    field(t("login.email"), f.email)[0], field(t("admin.user_name"), f.name)[0], field(t("admin.user_role"), f.role)[0],
    field(t("admin.user_password"), f.password, t("account.password_hint"))[0],
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, submit, h("button", { type: "button", class: "secondary", onclick: onClose },
      t("common.cancel"))));
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    submit.disabled = true;
    try {
      const user = await api("POST", "/users", { json: { email: f.email.value.trim(), name: f.name.value.trim(),
        role: f.role.value, password: f.password.value } });
      onClose();
      reload(t("admin.user_created", { email: user.email }));
    } catch (err) {
      message.append(alertBox(errorText(err)));
    } finally {
      submit.disabled = false;
    }
  });
  queueMicrotask(() => f.email.focus());
  return form;
}

/**
 * The instant the audit filter's day starts where the admin is: local midnight of `day` ("YYYY-MM-DD") as an ISO
 * time in UTC ("2026-12-01T23:00:00.000Z" in Madrid's winter).  A naive "T00:00:00" was read by the server as UTC
 * midnight, an hour or two off the day the admin picked.  "" for no day.
 */
export function sinceInstant(day) {
  if (!day) return "";
  const [y, m, d] = day.split("-").map(Number);
  return new Date(y, m - 1, d).toISOString();
}

// ------------------------------------------------------------------------------------------------ tokens
function tokensPage() {
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const secretArea = h("div");
  const listArea = h("div", { class: "table-scroll" });
  const formArea = h("div");
  const newButton = disclosure(t("admin.token_new"), formArea,
    (close) => newTokenForm(close, (created) => { showSecret(secretArea, created); load(); }), { id: "new-token" });

  async function load() {
    let rows;
    try {
      rows = await api("GET", "/tokens");
    } catch (err) {
      clear(listArea).append(alertBox(errorText(err)));
      return;
    }
    clear(listArea).append(tokensTable(rows, message, secretArea, load));
  }
  load();
  return [h("p", { class: "lead" }, t("admin.tokens_lead")), h("div", { class: "actions wrap" }, newButton), formArea,
    secretArea, h("div", { class: "card" }, message, listArea)];
}

/** The token of `created` shown once, with a copy button. */
function showSecret(area, created) {
  const input = h("input", { readonly: true, value: created.token, id: "token-secret", class: "secret",
    spellcheck: "false", "aria-label": t("admin.token_secret") });
  const copy = h("button", { type: "button", class: "secondary small" }, t("admin.token_copy"));
  const copied = h("span", { class: "hint", "aria-live": "polite" });
  copy.addEventListener("click", async () => {
    input.select();
    try {
      await navigator.clipboard.writeText(created.token);
      copied.textContent = t("admin.token_copied");
    } catch (_) {
      copied.textContent = t("admin.token_copy_by_hand");
    }
  });
  clear(area).append(h("div", { class: "notice warning", role: "status", id: "token-once" },
    h("strong", {}, t("admin.token_once", { id: created.id })), h("div", { class: "secret-row" }, input, copy), copied));
}

function tokenState(tok) {
  const kind = { active: "status-done", expired: "status-superseded", revoked: "status-failed" }[tok.state];
  return h("span", { class: `badge ${kind}` }, t(`admin.token_${tok.state}`));
}

function tokensTable(rows, message, secretArea, reload) {
  if (!rows.length) return h("p", { class: "empty" }, t("admin.tokens_none"));
  const body = rows.map((tok) => {
    const live = tok.state === "active";
    const rotate = live ? h("button", { type: "button", class: "secondary small", "data-action": "rotate" },
      t("admin.token_rotate")) : null;
    const revoke = tok.state !== "revoked" ? h("button", { type: "button", class: "danger small", "data-action": "revoke" },
      t("admin.token_revoke")) : null;
    if (rotate) {
      rotate.addEventListener("click", async () => {
        clear(message);
        try {
          const answer = await api("POST", `/tokens/${tok.id}/rotate`, { json: { grace_hours: 24 } });
          showSecret(secretArea, answer.new);
          reload();
        } catch (err) {
          message.append(alertBox(errorText(err)));
        }
      });
    }
    if (revoke) {
      revoke.addEventListener("click", () => confirmErase({
        title: t("admin.token_revoke_title", { id: tok.id }), text: t("admin.token_revoke_text"),
        confirmText: t("admin.token_revoke"),
        onConfirm: async () => {
          await api("POST", `/tokens/${tok.id}/revoke`);
          reload();
        } }));
    }
    return h("tr", { "data-token-id": String(tok.id), "data-state": tok.state },
      h("td", { class: "num" }, String(tok.id)),
      h("td", { class: "break" }, tok.label || "—"),
      h("td", {}, t(`role.${tok.role}`)),
      h("td", { class: "break" }, tok.scopes ? h("ul", { class: "plain" }, tok.scopes.map((s) =>
        h("li", { title: s }, scopeLabel(s)))) : t("admin.token_all_scopes")),
      h("td", {}, dateTime(tok.created_at)),
      h("td", {}, tok.expires_at ? dateTime(tok.expires_at) : t("admin.token_never")),
      h("td", {}, tokenState(tok)),
      h("td", {}, h("div", { class: "row-actions" }, rotate, revoke)));
  });
  return h("table", { class: "data", id: "tokens-table" },
    h("thead", {}, h("tr", {}, ["#", t("admin.token_label"), t("admin.user_role"), t("admin.token_scopes"),
      t("admin.token_created"), t("admin.token_expires"), t("admin.user_state"), ""].map((c) => h("th", { scope: "col" }, c)))),
    h("tbody", {}, body));
}

function newTokenForm(onClose, onCreated) {
  const f = {
    label: h("input", { name: "label", maxlength: 200, autocomplete: "off" }),
    role: roleSelect("role", "clinician"),
    days: h("input", { name: "expires_days", inputmode: "decimal", autocomplete: "off", value: "365" }),
  };
  const scopeBoxes = h("div", { class: "scopes" });
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const submit = h("button", { type: "submit", disabled: true }, t("admin.token_create"));
  const form = h("form", { class: "card form-grid", id: "new-token-form", "aria-label": t("admin.token_new") },
    h("h2", {}, t("admin.token_new")),
    field(t("admin.token_label"), f.label, t("admin.token_label_hint"))[0],
    field(t("admin.user_role"), f.role)[0],
    field(t("admin.token_days"), f.days, t("admin.token_days_hint"))[0],
    h("fieldset", { class: "wide scope-choice" }, h("legend", {}, t("admin.token_scopes")),
      h("p", { class: "hint" }, t("admin.token_scopes_hint")), scopeBoxes),
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, submit, h("button", { type: "button", class: "secondary", onclick: onClose },
      t("common.cancel"))));
  let maxDays;   // GET /options token_max_days (app/choices.py TOKEN_MAX_DAYS; the submit button waits for it)
  options().then((opts) => {
    scopeBoxes.append(...(opts.token_scopes || []).map((s) => h("label", { class: "radio", title: s },
      h("input", { type: "checkbox", name: "scope", value: s }), scopeLabel(s))));
    maxDays = opts.token_max_days;
    submit.disabled = false;
  }).catch((err) => message.append(alertBox(errorText(err))));
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    const days = parseDecimal(f.days.value);
    const tooLong = days !== null && days > maxDays;
    if (Number.isNaN(days) || (days !== null && days <= 0) || tooLong) {
      f.days.setAttribute("aria-invalid", "true");
      message.append(alertBox(tooLong ? t("admin.token_days_too_long", { max: String(maxDays) })
        : t("admin.token_days_invalid", { example: num(365, 0) })));
      f.days.focus();
      return;
    }
    f.days.removeAttribute("aria-invalid");
    const scopes = [...scopeBoxes.querySelectorAll("input:checked")].map((i) => i.value);
    submit.disabled = true;
    try {
      const created = await api("POST", "/tokens", { json: { label: f.label.value.trim(), role: f.role.value,
        expires_days: days, scopes: scopes.length ? scopes : null } });
      onClose();
      onCreated(created);
    } catch (err) {
      message.append(alertBox(errorText(err)));
    } finally {
      submit.disabled = false;
    }
  });
  queueMicrotask(() => f.label.focus());
  return form;
}

// ------------------------------------------------------------------------------------------------- audit
function auditPage() {
  const f = {
    action: h("select", { name: "action" }, h("option", { value: "" }, t("admin.audit_any"))),
    user: h("select", { name: "user_id" }, h("option", { value: "" }, t("admin.audit_any"))),
    patient: h("input", { name: "patient_id", inputmode: "numeric", autocomplete: "off", size: 6 }),
    since: h("input", { name: "since", type: "date" }),
  };
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const listArea = h("div", { class: "table-scroll" });
  const older = h("button", { type: "button", class: "secondary", id: "audit-older", hidden: true }, t("admin.audit_older"));
  const newest = h("button", { type: "button", class: "secondary", id: "audit-newest", hidden: true },
    t("admin.audit_newest"));
  const pageNote = h("span", { class: "hint", id: "audit-page" });
  const filters = h("form", { class: "card toolbar audit-filters", role: "search", "aria-label": t("admin.audit_filters") },
    field(t("admin.audit_action"), f.action)[0], field(t("admin.audit_user"), f.user)[0],
    field(t("admin.audit_patient"), f.patient)[0], field(t("admin.audit_since"), f.since)[0],
    h("div", { class: "actions" }, h("button", { type: "submit" }, t("admin.audit_apply"))));
  let pages = [];   // the before_id of each page shown (null: the newest)

  options().then((opts) => {
    f.action.append(...(opts.audit_actions || []).map((a) => h("option", { value: a }, label("audit_action", a))));
  }).catch((err) => message.append(alertBox(errorText(err))));
  api("GET", "/users").then((users) => {
    f.user.append(...users.map((u) => h("option", { value: String(u.id) }, u.name || u.email)));
  }).catch(() => { /* the log still works without the user menu */ });

  async function load(beforeId) {
    clear(message);
    const patient = f.patient.value.trim();
    if (patient && !/^\d+$/.test(patient)) {
      message.append(alertBox(t("admin.audit_patient_invalid")));
      f.patient.focus();
      return;
    }
    let events;
    try {
      events = await api("GET", "/audit", { query: { action: f.action.value, user_id: f.user.value, patient_id: patient,
        since: sinceInstant(f.since.value), before_id: beforeId, limit: AUDIT_PAGE } });
    } catch (err) {
      message.append(alertBox(errorText(err)));
      return;
    }
    clear(listArea).append(auditTable(events));
    pageNote.textContent = t("admin.audit_page", { n: pages.length, count: events.length });
    older.hidden = events.length < AUDIT_PAGE;
    older.dataset.before = events.length ? String(Math.min(...events.map((e) => e.id))) : "";
    newest.hidden = pages.length <= 1;
  }
  filters.addEventListener("submit", (e) => { e.preventDefault(); pages = [null]; load(null); });
  older.addEventListener("click", () => { const b = Number(older.dataset.before); pages.push(b); load(b); });
  newest.addEventListener("click", () => { pages = [null]; load(null); });
  pages = [null];
  load(null);
  return [filters, h("div", { class: "card" }, message, listArea,
    h("div", { class: "actions wrap pager" }, newest, older, pageNote))];
}

function auditTable(events) {
  if (!events.length) return h("p", { class: "empty" }, t("admin.audit_none"));
  return h("table", { class: "data", id: "audit-table" },
    h("thead", {}, h("tr", {}, [t("admin.audit_when"), t("admin.audit_who"), t("admin.audit_action"),
      t("admin.audit_what"), t("admin.audit_status"), t("admin.audit_detail")].map((c) => h("th", { scope: "col" }, c)))),
    h("tbody", {}, events.map((e) => h("tr", { "data-event-id": String(e.id), "data-action": e.action },
      h("td", { class: "nowrap" }, dateTime(e.at)),
      h("td", { class: "break" }, e.actor || t(`admin.actor_${e.actor_kind}`)),
      h("td", {}, label("audit_action", e.action)),
      h("td", { class: "break" }, e.patient_id ? h("a", { href: `#/patients/${e.patient_id}` },
        t("admin.audit_patient_n", { id: e.patient_id })) : null, e.resource ? h("div", { class: "hint" }, e.resource) : null),
      h("td", { class: "num" }, e.status == null ? "—" : String(e.status)),
      h("td", { class: "break" }, e.detail || "—")))));
}
