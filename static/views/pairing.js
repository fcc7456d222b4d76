// The results page's pairing card (issue 15 §2, "two sessions paired"): a one-knee session paired with another
// session of the patient, of the other knee (POST /sessions/{id}/pair {session_id, knee}; DELETE to undo), so that
// processing either gives both knees overlaid and the limb symmetry index, as `session.json` "paired_session" does
// for the CLI.  Pairing supersedes both sessions' analyses: the card then offers to process both knees now (the
// patient's side as the involved knee) and follows the job to the new analysis.

import { api } from "../api.js";
import { h, clear, alertBox, errorText, date } from "../dom.js";
import { t, lang } from "../i18n.js";
import { canEdit, navigate } from "../app.js";
import { followJob } from "./cycles.js";

/** The pairing card of `session` (of `patient`). */
export function pairingSection(session, patient) {
  const status = h("div", { id: "pair-status", role: "status", "aria-live": "polite" });
  const body = h("div", { id: "pair-body" });
  const section = h("section", { class: "card pairing", id: "pairing", "aria-labelledby": "h-pairing" },
    h("h2", { id: "h-pairing" }, t("pair.title")), h("p", { class: "hint" }, t("pair.hint")), body, status);
  (async () => {
    let sessions;
    try {
      sessions = await api("GET", `/patients/${session.patient_id}/sessions`);
    } catch (err) {
      body.append(alertBox(errorText(err)));
      return;
    }
    if (session.paired_session_id) paired(body, status, session, sessions);
    else unpaired(body, status, session, patient, sessions);
  })();
  return section;
}

function paired(body, status, session, sessions) {
  const other = sessions.find((s) => s.id === session.paired_session_id);
  const otherText = other ? t("compare.option", { id: other.id, date: date(other.date) }) : `#${session.paired_session_id}`;
  body.append(h("p", { id: "pair-state" }, t("pair.state", { other: otherText, knee: t(`pair.knee.${session.knee}`) })));
  // the pairing's warnings (sessions of different dates), handed over by the request that paired them
  const warnings = JSON.parse(sessionStorage.getItem("pair-warnings") || "[]");
  sessionStorage.removeItem("pair-warnings");
  for (const w of warnings) body.append(h("p", { class: "warning pair-warning" }, w.message[lang()] || w.message.en));
  if (!canEdit()) return;
  const process = h("button", { type: "button", class: "primary", id: "pair-process" }, t("pair.process"));
  const undo = h("button", { type: "button", class: "secondary", id: "pair-undo" }, t("pair.undo"));
  process.addEventListener("click", async () => {
    process.disabled = true;
    try {
      const job = await api("POST", `/sessions/${session.id}/process`, { json: { lang: lang() } });
      await followJob(session.id, job.job_id, status, t("pair.processing"), () => { process.disabled = false; });
    } catch (err) {
      clear(status).append(alertBox(errorText(err)));
      process.disabled = false;
    }
  });
  undo.addEventListener("click", async () => {
    undo.disabled = true;
    try {
      await api("DELETE", `/sessions/${session.id}/pair`);
      navigate(`#/sessions/${session.id}`);
    } catch (err) {
      clear(status).append(alertBox(errorText(err)));
      undo.disabled = false;
    }
  });
  body.append(h("div", { class: "actions wrap" }, process, undo));
}

function unpaired(body, status, session, patient, sessions) {
  const candidates = sessions.filter((s) => s.id !== session.id);
  if (!candidates.length) {
    body.append(h("p", { class: "hint", id: "pair-none" }, t("pair.none")));
    return;
  }
  if (!canEdit()) return;
  const select = h("select", { id: "pair-with", name: "pair_with" }, h("option", { value: "" }, t("pair.choose")),
    candidates.map((s) => h("option", { value: String(s.id) }, t("compare.option", { id: s.id, date: date(s.date) }))));
  // no default knee: a preselected one, left unchanged by mistake, would swap the knees (the server checks the
  // choice against the side the file names say, when they say one)
  const knee = h("select", { id: "pair-knee", name: "knee" }, h("option", { value: "" }, t("pair.choose_knee")),
    ["right", "left"].map((side) => h("option", { value: side }, t(`pair.knee.${side}`))));
  const button = h("button", { type: "button", class: "primary", id: "pair-button", disabled: true }, t("pair.pair"));
  const enable = () => { button.disabled = !select.value || !knee.value; };
  select.addEventListener("change", enable);
  knee.addEventListener("change", enable);
  button.addEventListener("click", async () => {
    button.disabled = true;
    try {
      const paired = await api("POST", `/sessions/${session.id}/pair`, { json: { session_id: Number(select.value), knee: knee.value } });
      if (paired.warnings && paired.warnings.length) sessionStorage.setItem("pair-warnings", JSON.stringify(paired.warnings));
      navigate(`#/sessions/${session.id}`);
    } catch (err) {
      clear(status).append(alertBox(errorText(err)));
      button.disabled = false;
    }
  });
  body.append(h("div", { class: "form-row" },
    h("label", { for: "pair-with" }, t("pair.with")), select,
    h("label", { for: "pair-knee" }, t("pair.this_knee")), knee, button));
}
