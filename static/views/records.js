// Correcting and erasing patients and sessions (PATCH / DELETE /patients/{id}, /sessions/{id}).
//
// Decisions: a correction sends only the fields whose value changed, with `If-Match` naming the version the
// form was filled from, so two people correcting the same record cannot silently overwrite each other (412 →
// "someone else changed it, reload").  An erasure always goes through a modal <dialog> that says what will be
// lost; erasing a patient (which cascades to every session, recording and report) also asks for the patient's
// identifier to be typed, and sends `If-Match` with the version shown.  Only admins see the delete buttons
// (the API refuses others with 403 anyway); clinicians may correct.

import { api } from "../api.js";
import { h, clear, field, alertBox, errorText, label } from "../dom.js";
import { t } from "../i18n.js";

/** The sentence for a failed correction or erasure (412 and 409 translated; else the server's sentence). */
export function changeError(err) {
  if (err && err.status === 412) return t("error.stale");
  if (err && err.status === 409 && /being processed/.test(err.detail || "")) return t("error.busy");
  return errorText(err);
}

function textOrNull(input) {
  const v = input.value.trim();
  return v === "" ? null : v;
}

function numberOrNull(input) {
  const v = input.value.trim().replace(",", ".");
  return v === "" ? null : Number(v);
}

/** `body` without the keys whose value equals `before`'s. */
function changedOnly(body, before) {
  return Object.fromEntries(Object.entries(body).filter(([k, v]) => (before[k] ?? null) !== v));
}

/**
 * A modal confirmation: `title`, `text`, and when `expect` is given an input that must match it.  Resolves
 * after `onConfirm()` succeeded (the dialog closes), or when cancelled (nothing happens).
 */
export function confirmErase({ title, text, expect = null, onConfirm }) {
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const typed = expect === null ? null : h("input", { name: "confirm", autocomplete: "off", spellcheck: "false" });
  const ok = h("button", { type: "submit", class: "danger" }, t("common.delete_for_good"));
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

/** The patient's edit form (PATCH with If-Match); `onSaved(patient)` after a successful save. */
export function editPatientForm(patient, onCancel, onSaved) {
  const f = {
    external_id: h("input", { name: "external_id", required: true, maxlength: 64, autocomplete: "off",
      value: patient.external_id }),
    side: h("select", { name: "side", required: true }, ["right", "left"].map((s) =>
      h("option", { value: s, selected: patient.side === s }, label("side", s)))),
    name: h("input", { name: "name", maxlength: 200, autocomplete: "off", value: patient.name || "" }),
    birth_date: h("input", { name: "birth_date", type: "date", value: patient.birth_date || "" }),
    height_cm: h("input", { name: "height_cm", inputmode: "decimal", value: patient.height_cm ?? "" }),
    mass_kg: h("input", { name: "mass_kg", inputmode: "decimal", value: patient.mass_kg ?? "" }),
    notes: h("textarea", { name: "notes", rows: 2 }, patient.notes || ""),
  };
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const submit = h("button", { type: "submit" }, t("common.save"));
  const form = h("form", { class: "card form-grid", id: "edit-patient", "aria-label": t("patient.edit") },
    h("h2", {}, t("patient.edit")),
    field(t("patient.external_id"), f.external_id)[0],
    field(t("patient.side"), f.side)[0],
    field(t("patient.name_optional"), f.name)[0],
    field(t("patient.birth_date"), f.birth_date)[0],
    field(t("patient.height_cm"), f.height_cm)[0],
    field(t("patient.mass_kg"), f.mass_kg)[0],
    h("div", { class: "wide" }, field(t("patient.notes"), f.notes)[0]),
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, submit,
      h("button", { type: "button", class: "secondary", onclick: onCancel }, t("common.cancel"))));
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    const body = changedOnly({
      external_id: f.external_id.value.trim(), side: f.side.value, name: textOrNull(f.name),
      birth_date: f.birth_date.value || null, height_cm: numberOrNull(f.height_cm), mass_kg: numberOrNull(f.mass_kg),
      notes: textOrNull(f.notes) }, patient);
    if (!Object.keys(body).length) { onCancel(); return; }
    submit.disabled = true;
    try {
      onSaved(await api("PATCH", `/patients/${patient.id}`, { json: body, ifMatch: patient.version }));
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
