// Correcting and erasing patients and sessions (PATCH / DELETE /patients/{id}, /sessions/{id}).
//
// Decisions: a correction sends only the fields whose value changed, with `If-Match` naming the version the
// form was filled from, so two people correcting the same record cannot silently overwrite each other (412 →
// "someone else changed it, reload").  An erasure always goes through a modal <dialog> that says what will be
// lost; erasing a patient (which cascades to every session, recording and report) also asks for the patient's
// identifier to be typed, and sends `If-Match` with the version shown.  Only admins see the delete buttons
// (the API refuses others with 403 anyway); clinicians may correct.

import { api } from "../api.js";
import { h, clear, field, alertBox, errorText, label, num, parseDecimal, decimalText } from "../dom.js";
import { t } from "../i18n.js";
import { options } from "../options.js";

/** The sentence for a failed correction or erasure (412 and 409 translated; else the server's sentence). */
export function changeError(err) {
  if (err && err.status === 412) return t("error.stale");
  if (err && err.status === 409 && /being processed/.test(err.detail || "")) return t("error.busy");
  return errorText(err);
}

/** The trimmed text of `input`, or null when empty. */
export function textOrNull(input) {
  const v = input.value.trim();
  return v === "" ? null : v;
}

/** `body` without the keys whose value equals `before`'s. */
function changedOnly(body, before) {
  return Object.fromEntries(Object.entries(body).filter(([k, v]) => (before[k] ?? null) !== v));
}

/**
 * A modal confirmation: `title`, `text`, and when `expect` is given an input that must match it; `confirmText`
 * names the button (default "delete for good").  Resolves
 * after `onConfirm()` succeeded (the dialog closes), or when cancelled (nothing happens).
 */
export function confirmErase({ title, text, expect = null, onConfirm, confirmText = null }) {
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const typed = expect === null ? null : h("input", { name: "confirm", autocomplete: "off", spellcheck: "false" });
  const ok = h("button", { type: "submit", class: "danger" }, confirmText || t("common.delete_for_good"));
  const cancel = h("button", { type: "button", class: "secondary" }, t("common.cancel"));
  const titleId = `confirm-title-${Date.now()}`;
  const dialog = h("dialog", { class: "confirm card", "aria-labelledby": titleId });
  const form = h("form", { method: "dialog" }, h("h2", { id: titleId }, title), h("p", {}, text),
    typed ? field(expect, typed)[0] : null, message, h("div", { class: "actions" }, ok, cancel));
  dialog.append(form);
  document.body.append(dialog);
  const close = () => { dialog.close(); dialog.remove(); };
  cancel.addEventListener("click", close);
  dialog.addEventListener("cancel", () => dialog.remove());
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    if (typed && typed.value.trim() !== expect) {
      message.append(alertBox(t("patient.delete_mismatch")));
      typed.focus();
      return;
    }
    ok.disabled = true;
    try {
      await onConfirm();
      close();
    } catch (err) {
      message.append(alertBox(changeError(err)));
    } finally {
      ok.disabled = false;
    }
  });
  dialog.showModal();
  (typed || cancel).focus();
  return dialog;
}

// an example of each measurement for the messages; the bounds are the API's (GET /options measure_ranges, from
// app/choices.py MEASURE_RANGES: open intervals)
const EXAMPLES = { height_cm: 165.5, mass_kg: 70.5 };

/**
 * The value of measurement input `input` (`name` of EXAMPLES) within `range` ({min, max}, both excluded), or an
 * error sentence in the UI language.
 */
function measure(input, name, fieldLabel, range) {
  const value = parseDecimal(input.value);
  const { min, max } = range;
  const example = EXAMPLES[name];
  if (value === null) return { value: null };
  if (Number.isNaN(value)) return { error: t("patient.number_invalid", { field: fieldLabel, example: num(example, 1) }) };
  if (!(value > min && value < max)) {
    return { error: t("patient.number_range", { field: fieldLabel, min: num(min, 0), max: num(max, 0) }) };
  }
  return { value };
}

/**
 * The patient form: a new patient (`patient` null: POST, then `onSaved(patient)`) or a correction (PATCH of the
 * changed fields with If-Match).  Height and mass are typed as text and read by parseDecimal, so "165,5" and
 * "165.5" are both 165.5 cm in every UI language (an <input type=number> follows the browser's locale instead);
 * their refusals are said in the UI language.  The sexes come from GET /options (app/choices.py SEX_NAMES).
 */
export function patientForm(patient, onCancel, onSaved) {
  const editing = Boolean(patient);
  const p = patient || {};
  const measureInput = (name) => h("input", { name, inputmode: "decimal", autocomplete: "off", spellcheck: "false",
    value: decimalText(p[name]) });
  const f = {
    external_id: h("input", { name: "external_id", required: true, maxlength: 100, autocomplete: "off",
      value: p.external_id || "" }),
    side: h("select", { name: "side", required: true }, ["right", "left"].map((s) =>
      h("option", { value: s, selected: p.side === s }, label("side", s)))),
    name: h("input", { name: "name", maxlength: 200, autocomplete: "off", value: p.name || "" }),
    birth_date: h("input", { name: "birth_date", type: "date", value: p.birth_date || "" }),
    sex: h("select", { name: "sex" }, h("option", { value: "" }, "—")),
    height_cm: measureInput("height_cm"),
    mass_kg: measureInput("mass_kg"),
    notes: h("textarea", { name: "notes", rows: 2 }, p.notes || ""),
  };
  const title = editing ? t("patient.edit") : t("patients.new");
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const submit = h("button", { type: "submit", disabled: true }, editing ? t("common.save") : t("patients.create"));
  const form = h("form", { class: "card form-grid", id: editing ? "edit-patient" : "new-patient", "aria-label": title },
    h("h2", {}, title),
    field(t("patient.external_id"), f.external_id, editing ? null : t("patient.external_id_hint"))[0],
    field(t("patient.side"), f.side, editing ? null : t("patient.side_hint"))[0],
    field(t("patient.name_optional"), f.name)[0],
    field(t("patient.birth_date"), f.birth_date)[0],
    field(t("patient.sex"), f.sex)[0],
    field(t("patient.height_cm"), f.height_cm, t("patient.decimal_hint", { example: num(165.5, 1) }))[0],
    field(t("patient.mass_kg"), f.mass_kg)[0],
    h("div", { class: "wide" }, field(t("patient.notes"), f.notes)[0]),
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, submit,
      h("button", { type: "button", class: "secondary", onclick: onCancel }, t("common.cancel"))));
  let ranges;   // GET /options measure_ranges (the submit button waits for them)
  options().then((opts) => {
    f.sex.append(...(opts.sexes || []).map((s) => h("option", { value: s, selected: p.sex === s }, label("sex", s))));
    ranges = opts.measure_ranges;
    submit.disabled = false;
  }).catch((err) => message.append(alertBox(errorText(err))));
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    for (const input of [f.height_cm, f.mass_kg]) input.removeAttribute("aria-invalid");
    const height = measure(f.height_cm, "height_cm", t("patient.height_cm"), ranges.height_cm);
    const mass = measure(f.mass_kg, "mass_kg", t("patient.mass_kg"), ranges.mass_kg);
    for (const [m, input] of [[height, f.height_cm], [mass, f.mass_kg]]) {
      if (m.error) {
        input.setAttribute("aria-invalid", "true");
        message.append(alertBox(m.error));
        input.focus();
        return;
      }
    }
    if (!f.external_id.value.trim()) {
      message.append(alertBox(t("patients.external_id_required")));
      f.external_id.focus();
      return;
    }
    const full = {
      external_id: f.external_id.value.trim(), side: f.side.value, name: textOrNull(f.name),
      birth_date: f.birth_date.value || null, sex: f.sex.value || null, height_cm: height.value, mass_kg: mass.value,
      notes: textOrNull(f.notes) };
    const body = editing ? changedOnly(full, patient) : full;
    if (!Object.keys(body).length) { onCancel(); return; }
    submit.disabled = true;
    try {
      onSaved(editing ? await api("PATCH", `/patients/${patient.id}`, { json: body, ifMatch: patient.version })
        : await api("POST", "/patients", { json: body }));
    } catch (err) {
      message.append(alertBox(changeError(err)));
    } finally {
      submit.disabled = false;
    }
  });
  queueMicrotask(() => f.external_id.focus());
  return form;
}

/** A session's edit form (date, step height, professional, notes; PATCH with If-Match). */
export function editSessionForm(session, dateText, onCancel, onSaved) {
  const f = {
    date: h("input", { type: "date", name: "date", value: session.date, required: true }),
    step: h("select", { name: "step_height_m" },
      h("option", { value: "", selected: session.step_height_m == null }, "—"),
      h("option", { value: "0.17", selected: session.step_height_m === 0.17 }, t("session.step_low")),
      h("option", { value: "0.34", selected: session.step_height_m === 0.34 }, t("session.step_high"))),
    professional: h("input", { name: "professional", maxlength: 200, value: session.professional || "" }),
    notes: h("textarea", { name: "notes", rows: 2 }, session.notes || ""),
  };
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const submit = h("button", { type: "submit" }, t("common.save"));
  const form = h("form", { class: "card form-grid", id: "edit-session", "aria-label": t("sessions.edit") },
    h("h2", {}, t("sessions.edit_title", { date: dateText })),
    h("p", { class: "hint wide" }, t("sessions.edit_hint")),
    field(t("session.date"), f.date)[0],
    session.task === "step_up" ? field(t("session.step_height"), f.step)[0] : null,
    field(t("session.professional"), f.professional)[0],
    h("div", { class: "wide" }, field(t("session.notes"), f.notes)[0]),
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, submit,
      h("button", { type: "button", class: "secondary", onclick: onCancel }, t("common.cancel"))));
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    const body = changedOnly({ date: f.date.value || null, professional: textOrNull(f.professional),
      notes: textOrNull(f.notes),
      ...(session.task === "step_up" ? { step_height_m: f.step.value ? Number(f.step.value) : null } : {}) }, session);
    if (!Object.keys(body).length) { onCancel(); return; }
    submit.disabled = true;
    try {
      onSaved(await api("PATCH", `/sessions/${session.id}`, { json: body, ifMatch: session.version }));
    } catch (err) {
      message.append(alertBox(changeError(err)));
    } finally {
      submit.disabled = false;
    }
  });
  queueMicrotask(() => f.date.focus());
  return form;
}
