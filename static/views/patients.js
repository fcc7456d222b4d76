// Patients list (search, new patient) and one patient's page (details, sessions, new session, ROM trend).

import { api } from "../api.js";
import { h, clear, field, alertBox, errorText, date, dateTime, num, label, disclosure } from "../dom.js";
import { t } from "../i18n.js";
import { navigate, canEdit, isAdmin, currentUser } from "../app.js";
import { confirmErase, patientForm, editSessionForm, changeError, textOrNull } from "./records.js";
import { options, fillSelect } from "../options.js";
import { ANGLES, drawTrend, purge } from "../charts.js";

/** The name shown for a patient: the name when given, else the external id. */
export function patientTitle(p) {
  return p.name ? `${p.name} (${p.external_id})` : p.external_id;
}

/** A status badge of a session. */
export function statusBadge(status) {
  return h("span", { class: `badge status-${status}` }, label("status", status));
}

// ------------------------------------------------------------------------------------------- list
export function patientsView() {
  const section = h("section", { class: "view" });
  const search = h("input", { type: "search", name: "q", autocomplete: "off", placeholder: t("patients.search_placeholder") });
  const [searchField] = field(t("patients.search"), search);
  const listArea = h("div", { class: "list-area", "aria-live": "polite" });
  const formArea = h("div");
  const newButton = disclosure(t("patients.new"), formArea, newPatientForm);
  section.append(
    h("div", { class: "title-row" }, h("h1", {}, t("patients.title")), canEdit() ? newButton : null),
    formArea,
    h("div", { class: "card" }, h("div", { class: "toolbar" }, searchField), listArea),
  );

  let seq = 0;
  async function refresh() {
    const mine = ++seq;
    try {
      const patients = await api("GET", "/patients", { query: { q: search.value.trim() } });
      if (mine !== seq) return;   // a newer search answered meanwhile
      clear(listArea).append(patientsTable(patients, search.value.trim()));
    } catch (err) {
      clear(listArea).append(alertBox(errorText(err)));
    }
  }
  let timer = null;
  search.addEventListener("input", () => {
    clearTimeout(timer);
    timer = setTimeout(refresh, 250);
  });
  refresh();
  return section;
}

function patientsTable(patients, q) {
  if (!patients.length) {
    return h("p", { class: "empty" }, q ? t("patients.none_found", { q }) : t("patients.none"));
  }
  const rows = patients.map((p) => h("tr", {},
    h("td", {}, h("a", { href: `#/patients/${p.id}` }, p.external_id)),
    h("td", {}, p.name || "—"),
    h("td", {}, label("side", p.side)),
    h("td", {}, date(p.birth_date)),
    h("td", {}, dateTime(p.created_at))));
  return h("table", { class: "data", id: "patients-table" },
    h("caption", { class: "visually-hidden" }, t("patients.title")),
    h("thead", {}, h("tr", {}, [t("patient.external_id"), t("patient.name"), t("patient.side"),
      t("patient.birth_date"), t("patient.created_at")].map((c) => h("th", { scope: "col" }, c)))),
    h("tbody", {}, rows));
}

function newPatientForm(onCancel) {
  return patientForm(null, onCancel, (patient) => navigate(`#/patients/${patient.id}`));
}

// ------------------------------------------------------------------------------------------ patient
export function patientView(id) {
  const section = h("section", { class: "view" }, h("p", { class: "loading" }, t("common.loading")));
  (async () => {
    let patient, sessions;
    try {
      [patient, sessions] = await Promise.all([api("GET", `/patients/${id}`), api("GET", `/patients/${id}/sessions`)]);
    } catch (err) {
      clear(section).append(h("h1", {}, t("patient.title")), alertBox(errorText(err)),
        h("p", {}, h("a", { href: "#/patients" }, t("common.back_to_patients"))));
      return;
    }
    const formArea = h("div");
    const reload = () => navigate(`#/patients/${id}`);
    const newSession = disclosure(t("sessions.new"), formArea, (close) => newSessionForm(id, close));
    const edit = disclosure(t("patient.edit"), formArea, (close) => patientForm(patient, close, reload));
    const erase = h("button", { type: "button", class: "danger", id: "delete-patient", onclick: () => confirmErase({
      title: t("patient.delete_title"), text: t("patient.delete_text", { id: patient.external_id }),
      expect: patient.external_id,
      onConfirm: async () => {
        await api("DELETE", `/patients/${id}`, { ifMatch: patient.version });
        navigate("#/patients");
      } }) }, t("patient.delete"));
    const trendArea = h("div", { class: "card" }, h("h2", {}, t("patient.trend")));
    const rowActions = { edit: (s) => editSession(s, formArea, reload), erase: (s) => eraseSession(s, reload) };
    clear(section).append(
      h("nav", { class: "crumbs", "aria-label": t("common.breadcrumbs") }, h("a", { href: "#/patients" }, t("nav.patients"))),
      h("div", { class: "title-row" }, h("h1", {}, patientTitle(patient)),
        h("div", { class: "actions wrap" }, canEdit() ? newSession : null, canEdit() ? edit : null,
          isAdmin() ? erase : null)),
      formArea,
      h("div", { class: "columns" },
        h("div", { class: "card" }, h("h2", {}, t("patient.details")), patientDetails(patient)),
        h("div", { class: "card grow" }, h("h2", {}, t("sessions.title")), sessionsTable(sessions, rowActions))),
      trendArea);
    loadTrend(id, trendArea, section);
  })();
  return section;
}

function patientDetails(p) {
  const rows = [
    [t("patient.external_id"), p.external_id], [t("patient.name"), p.name || "—"], [t("patient.side"), label("side", p.side)],
    [t("patient.birth_date"), date(p.birth_date)], [t("patient.sex"), label("sex", p.sex)],
    [t("patient.height_cm"), p.height_cm == null ? "—" : num(p.height_cm, 1)],
    [t("patient.mass_kg"), p.mass_kg == null ? "—" : num(p.mass_kg, 1)], [t("patient.notes"), p.notes || "—"],
    [t("patient.created_at"), dateTime(p.created_at)],
  ];
  return h("dl", { class: "details" }, rows.map(([k, v]) => [h("dt", {}, k), h("dd", {}, v)]));
}

// The session's edit form in `formArea` (the full session, with its version, is read first).
async function editSession(summary, formArea, onSaved) {
  clear(formArea);
  try {
    const session = await api("GET", `/sessions/${summary.id}`);
    formArea.append(editSessionForm(session, date(session.date), () => clear(formArea), onSaved));
  } catch (err) {
    formArea.append(alertBox(changeError(err)));
  }
}

// The confirmation, then DELETE with the version just read.
function eraseSession(summary, onDone) {
  confirmErase({
    title: t("sessions.delete_title", { date: date(summary.date) }), text: t("sessions.delete_text"),
    onConfirm: async () => {
      const session = await api("GET", `/sessions/${summary.id}`);
      await api("DELETE", `/sessions/${summary.id}`, { ifMatch: session.version });
      onDone();
    } });
}

function sessionsTable(sessions, rowActions) {
  if (!sessions.length) return h("p", { class: "empty" }, t("sessions.none"));
  const rows = sessions.map((s) => {
    const done = s.status === "done" || s.status === "superseded";
    return h("tr", {},
      h("td", { class: "nowrap" }, h("a", { href: done ? `#/sessions/${s.id}` : `#/sessions/${s.id}/wizard` }, date(s.date))),
      h("td", {}, label("task", s.task)),
      h("td", { class: "num" }, String(s.n_recordings ?? 0)),
      h("td", {}, statusBadge(s.status)),
      h("td", {}, h("div", { class: "row-actions" },
        h("a", { href: `#/sessions/${s.id}/wizard`, class: "button-link secondary small" }, t("sessions.open_wizard")),
        done ? h("a", { href: `#/sessions/${s.id}`, class: "button-link small" }, t("sessions.open_results")) : null,
        canEdit() ? h("button", { type: "button", class: "secondary small", "data-action": "edit-session",
          onclick: () => rowActions.edit(s) }, t("sessions.edit")) : null,
        isAdmin() ? h("button", { type: "button", class: "danger small", "data-action": "delete-session",
          onclick: () => rowActions.erase(s) }, t("sessions.delete")) : null)));
  });
  return h("table", { class: "data", id: "sessions-table" },
    h("thead", {}, h("tr", {}, [t("session.date"), t("session.task"), t("session.recordings"), t("session.status"), ""]
      .map((c) => h("th", { scope: "col" }, c)))),
    h("tbody", {}, rows));
}

function newSessionForm(patientId, onCancel) {
  const today = new Date();
  const iso = new Date(today.getTime() - today.getTimezoneOffset() * 60000).toISOString().slice(0, 10);
  const f = {
    date: h("input", { type: "date", name: "date", value: iso, required: true }),
    task: h("select", { name: "task" }),  // from GET /options (app/choices.py), the tasks the server analyses
    step: h("select", { name: "step_height_m" },
      h("option", { value: "0.17" }, t("session.step_low")), h("option", { value: "0.34" }, t("session.step_high"))),
    // the logged-in user is who usually records the session: pre-filled, and can be changed
    professional: h("input", { name: "professional", maxlength: 200, autocomplete: "name",
      value: (currentUser() || {}).name || (currentUser() || {}).email || "" }),
    notes: h("textarea", { name: "notes", rows: 2 }),
  };
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  // disabled until the task menu is filled: a click before GET /options answers would send no task (422)
  const submit = h("button", { type: "submit", disabled: true }, t("sessions.create"));
  const form = h("form", { class: "card form-grid", "aria-label": t("sessions.new") },
    h("h2", {}, t("sessions.new")),
    field(t("session.date"), f.date)[0],
    field(t("session.task"), f.task)[0],
    field(t("session.step_height"), f.step, t("session.step_height_hint"))[0],
    field(t("session.professional"), f.professional)[0],
    h("div", { class: "wide" }, field(t("session.notes"), f.notes)[0]),
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, submit,
      h("button", { type: "button", class: "secondary", onclick: onCancel }, t("common.cancel"))));
  const stepRow = f.step.closest(".field") || f.step.parentElement;
  const showStep = () => { if (stepRow) stepRow.hidden = f.task.value !== "step_up"; };
  f.task.addEventListener("change", showStep);
  options().then((opts) => { fillSelect(f.task, "task", opts.tasks); showStep(); submit.disabled = false; })
    .catch((err) => message.append(alertBox(errorText(err))));
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    if (!f.task.value) return;  // the task menu is not filled yet (the button is disabled until it is)
    clear(message);
    submit.disabled = true;
    try {
      const session = await api("POST", `/patients/${patientId}/sessions`, { json: {
        date: f.date.value || null, task: f.task.value,
        step_height_m: f.task.value === "step_up" ? Number(f.step.value) : null,
        professional: textOrNull(f.professional), notes: textOrNull(f.notes) } });
      navigate(`#/sessions/${session.id}/wizard`);
    } catch (err) {
      message.append(alertBox(errorText(err)));
    } finally {
      submit.disabled = false;
    }
  });
  return form;
}

async function loadTrend(patientId, area, section) {
  let trend;
  try {
    trend = await api("GET", `/patients/${patientId}/trend`);
  } catch (err) {
    area.append(alertBox(errorText(err)));
    return;
  }
  const points = (trend && trend.points) || [];
  if (!points.length) {
    area.append(h("p", { class: "empty" }, t("patient.trend_none")));
    return;
  }
  const chart = h("div", { class: "chart", id: "trend-chart", role: "img", "aria-label": t("patient.trend_alt") });
  // one series only (GET /trend: one filter and pipeline version); sessions analysed otherwise are named, not mixed in
  const series = h("p", { class: "hint", id: "trend-series" },
    t("patient.trend_series", { filter: label("filter", trend.filter), version: trend.pipeline_version,
      angles: label("angle_convention", trend.angle_method), calibration: label("calibration", trend.calibration) }));
  const leftOut = (trend.left_out || []).length ? h("p", { class: "hint", id: "trend-left-out" }, t("patient.trend_left_out",
    { sessions: trend.left_out.map((x) => `#${x.session_id} (${date(x.date)})`).join(", ") })) : "";
  area.append(h("p", { class: "hint" }, t("patient.trend_hint")), series, leftOut, chart, trendTable(points));
  try {
    await drawTrend(chart, points);
  } catch (err) {
    chart.replaceWith(alertBox(errorText(err)));
  }
  const observer = new MutationObserver(() => { if (!section.isConnected) { purge(chart); observer.disconnect(); } });
  observer.observe(document.getElementById("main"), { childList: true });
}

function trendTable(points) {
  const rangeOf = (p, a) => (p.rom_deg && p.rom_deg[a] && p.rom_deg[a].range) || null;
  return h("details", { class: "trend-table" }, h("summary", {}, t("patient.trend_table")),
    h("table", { class: "data" },
      h("thead", {}, h("tr", {}, [t("session.date"), t("results.filter"),
        ...ANGLES.map((a) => `${label("angle", a)} · ${t("results.rom_range")} (°)`)].map((c) => h("th", { scope: "col" }, c)))),
      h("tbody", {}, points.map((p) => h("tr", {},
        h("td", {}, h("a", { href: `#/sessions/${p.session_id}?analysis_id=${p.analysis_id}` }, date(p.date))),
        h("td", {}, label("filter", p.filter)),
        ANGLES.map((a) => {
          const r = rangeOf(p, a);
          return h("td", { class: "num" }, r ? `${num(r.mean)} ± ${num(r.sd)}` : "—");
        }))))));
}
