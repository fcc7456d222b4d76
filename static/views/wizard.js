// The session wizard: 1 sensors ↔ segments, 2 the four recordings of each sensor, 3 filter and language →
// process, with a progress bar while the job runs.
//
// Decisions:
// - The sensor labels / MAC typed in step 1 stay in this browser (localStorage per session): what the
//   server needs is the segment of each file, and each drop zone of step 2 is tied to a segment and a role,
//   sent as the `segment` / `role` form fields of its upload.
// - Swapped sensors are caught from the sensor serials the SERVER stored with each recording (`device` of
//   GET /sessions/{id}: the MAC a MetaBase file's name carries, read by app/pipeline/ingestion/provenance.py
//   sensor_of_file_name, any device name), so the browser keeps no copy of the naming rule.  A zone whose stored
//   files the server's `sensor_warnings` name (one sensor on both segments) shows that sentence while no MAC is
//   typed in step 1; with a MAC typed (the more specific case), files carrying the MAC given to the OTHER
//   segment show "sensors swapped?", and files
//   carrying a third MAC "not this segment's sensor".  A MAC that matches neither is not flagged when only the
//   other segment's MAC is known (it is then presumably this sensor's).  Only a warning: the upload goes ahead,
//   and it is recomputed whenever the zone is drawn (after each upload), so it also appears for files stored
//   before the MAC was typed.
// - Each zone uploads as soon as files are dropped or picked (several files per zone: a MetaBase recording
//   is three CSV files).  The answer's ingestion check (app.pipeline.ingestion over every stored file of the session)
//   is shown at once, before processing; "Process" stays disabled until it is ok.
// - Files without a zone (e.g. session.json, or uploaded through the API without segment/role) are listed
//   in an "other files" zone; the ingestion rules recognise them from their names.
// - One continuous recording per sensor (the "whole protocol" zone, role `continuous`, or recognised from its
//   name) is split by the server's check, whose answer carries each sensor's cuts and a motion trace
//   (`ingestion.splits`).  Step 2 draws the trace with the parts over it; the clinician drags a cut (or moves it
//   with the arrow keys, or types its seconds) and confirms: PUT /sessions/{id}/split stores the cuts ON THE
//   SERVER (app/store/recordings.py set_split), the files are checked again with them, and the processing uses
//   them (session.json "split").  "Back to the automatic cuts" stores none.  The browser keeps nothing.
// - Every sentence of the check is shown in the UI's language (`message_texts` / `error_message`: the server
//   stores codes and renders them in es/en/pt); a check stored before that falls back to its English text.
// - Progress: the API's server-sent event stream (GET /events, app/web/api/webhooks.py: `event: job` with the status,
//   progress and stage of each of the clinic's jobs, checked every second) through an EventSource; the job's end
//   reads GET /jobs/{id} once for its error, log and analysis.  If the stream cannot be opened, or breaks twice
//   without coming back, or ends (a closed login: `event: end`), the bar falls back to GET /jobs/{id} every 300 ms.
//   <progress> carries the fraction; the job box says which way the news came (data-via="stream" | "polling").

import { api, apiUrl, upload } from "../api.js";
import { h, append, clear, field, alertBox, errorText, date, bytes, label, num } from "../dom.js";
import { t, lang } from "../i18n.js";
import { options, fillSelect } from "../options.js";
import { patientTitle, statusBadge } from "./patients.js";
import { canEdit } from "../app.js";

export const SEGMENTS = ["thigh", "shank"];
export const ROLES = ["mag_calibration", "standing", "lying", "task"];
// the upload zones of a segment: the four recordings, or one recording of the whole protocol (split by the server)
const ZONE_ROLES = [...ROLES, "continuous"];
const POLL_MS = 300;

// ------------------------------------------------------------------------------ sensors (step 1 state)
function sensorsKey(sessionId) {
  return `chakamo.sensors.${sessionId}`;
}

function loadSensors(sessionId) {
  try {
    const s = JSON.parse(localStorage.getItem(sensorsKey(sessionId)));
    if (Array.isArray(s) && s.length === 2) return s;
  } catch (_) { /* nothing stored */ }
  return [{ label: "", segment: "thigh" }, { label: "", segment: "shank" }];
}

function saveSensors(sessionId, sensors) {
  try { localStorage.setItem(sensorsKey(sessionId), JSON.stringify(sensors)); } catch (_) { /* storage off */ }
}

// A MAC inside a typed label: six hex pairs joined by ":" or "-" ("D4:F1:A2:B3:C4:E5"), or 12 hex digits.
const TYPED_MAC = /(?:^|[^0-9A-Fa-f])((?:[0-9A-Fa-f]{2}[:-]){5}[0-9A-Fa-f]{2}|[0-9A-Fa-f]{12})(?![0-9A-Fa-f])/;

/** The MAC (12 upper-case hex digits) typed in a step-1 label, or null. */
export function typedMac(text) {
  const m = TYPED_MAC.exec(text || "");
  return m ? m[1].replace(/[:-]/g, "").toUpperCase() : null;
}

function showMac(mac) {
  return mac.match(/../g).join(":");
}

/** The sentence warning that the recordings `recs` stored in a zone of `segment` come from the wrong sensor
 * (module decisions: the server's `device` of each recording), or null. */
function macWarning(ctx, segment, recs) {
  if (!segment) return null;
  const otherSegment = SEGMENTS.find((s) => s !== segment);
  const macs = [...new Set(recs.map((r) => r.device).filter(Boolean))];
  const macOn = (seg) => typedMac((ctx.sensors.find((s) => s.segment === seg) || {}).label);
  const own = macOn(segment);
  const other = macOn(otherSegment);
  if (!own && !other) {   // no MAC typed: the server's check of its stored serials, already in every language
    const names = new Set(recs.map((r) => r.file_name));
    const both = (ctx.session.sensor_warnings || []).find((w) => names.has((w.params || {})[`${segment}_file`]));
    return both ? ((both.message || {})[lang()] || t("wizard.mac_both_segments", { mac: showMac(both.params.sensor) }))
      : null;
  }
  if (other && other !== own && macs.includes(other)) {
    return t(`wizard.mac_swapped.${segment}`, { mac: showMac(other) });
  }
  const strangers = own ? macs.filter((m) => m !== own && m !== other) : [];
  if (strangers.length) {
    return t(`wizard.mac_unknown.${segment}`, { mac: strangers.map(showMac).join(", "), expected: showMac(own) });
  }
  return null;
}

/** "Sensor 1 (label)" of the sensor placed on `segment`. */
function sensorOn(sensors, segment) {
  const i = sensors.findIndex((s) => s.segment === segment);
  if (i < 0) return "";
  const name = t("wizard.sensor_n", { n: i + 1 });
  return sensors[i].label ? `${name} · ${sensors[i].label}` : name;
}

// ---------------------------------------------------------------------------------------------- view
/** The wizard of session `sessionId` (#/sessions/{id}/wizard). */
export function wizardView(sessionId) {
  const section = h("section", { class: "view wizard" }, h("p", { class: "loading" }, t("common.loading")));
  const ctx = { sessionId, section, session: null, patient: null, sensors: loadSensors(sessionId), step: 1 };
  (async () => {
    try {
      ctx.session = await api("GET", `/sessions/${sessionId}`);
      ctx.patient = await api("GET", `/patients/${ctx.session.patient_id}`);
    } catch (err) {
      clear(section).append(h("h1", {}, t("wizard.title")), alertBox(errorText(err)),
        h("p", {}, h("a", { href: "#/patients" }, t("common.back_to_patients"))));
      return;
    }
    const active = (ctx.session.jobs || []).find((j) => j.status === "queued" || j.status === "running");
    ctx.step = active ? 3 : (ctx.session.recordings || []).length ? 2 : 1;
    renderShell(ctx);
    if (active) showProgress(ctx, active.id);
  })();
  return section;
}

function renderShell(ctx) {
  const { session, patient } = ctx;
  ctx.stepNav = h("ol", { class: "steps" });
  ctx.body = h("div", { class: "step-body" });
  ctx.ingestionArea = h("div", { class: "ingestion", "aria-live": "polite" });
  ctx.splitArea = h("div", { class: "split-area" });
  const hasResults = (session.analyses || []).length > 0;
  append(clear(ctx.section), [
    h("nav", { class: "crumbs", "aria-label": t("common.breadcrumbs") },
      h("a", { href: "#/patients" }, t("nav.patients")), " › ",
      h("a", { href: `#/patients/${patient.id}` }, patientTitle(patient))),
    h("div", { class: "title-row" },
      h("h1", {}, t("wizard.title_session", { date: date(session.date) })),
      ctx.badge = statusBadge(session.status),
      hasResults ? h("a", { href: `#/sessions/${session.id}`, class: "button-link secondary" }, t("wizard.see_results")) : null),
    h("p", { class: "lead" }, t(`wizard.lead_${patient.side}`),
      session.step_height_m ? ` ${t("wizard.step_height", { cm: num(session.step_height_m * 100, 0) })}` : ""),
    canEdit() ? null : h("div", { class: "notice info", role: "status" }, t("wizard.read_only")),
    ctx.stepNav, ctx.body]);
  goTo(ctx, ctx.step);
}

function goTo(ctx, step) {
  ctx.step = step;
  clear(ctx.stepNav);
  ["wizard.step1", "wizard.step2", "wizard.step3"].forEach((key, i) => {
    const n = i + 1;
    const b = h("button", { type: "button", class: "step", "aria-current": n === step ? "step" : null,
      onclick: () => goTo(ctx, n) }, h("span", { class: "step-n" }, String(n)), t(key));
    ctx.stepNav.append(h("li", {}, b));
  });
  clear(ctx.body);
  if (step === 1) ctx.body.append(sensorsStep(ctx));
  else if (step === 2) ctx.body.append(uploadStep(ctx));
  else ctx.body.append(processStep(ctx));
  const heading = ctx.body.querySelector("h2");
  if (heading) heading.setAttribute("tabindex", "-1");
  if (step === 3 && ctx.activeJob) showProgress(ctx, ctx.activeJob);   // back on step 3: the job still runs
}

function navButtons(ctx, { back, next, nextLabel }) {
  return h("div", { class: "actions" },
    back ? h("button", { type: "button", class: "secondary", onclick: () => { goTo(ctx, back); focusHeading(ctx); } },
      t("common.back")) : null,
    next ? h("button", { type: "button", class: "next", onclick: () => { goTo(ctx, next); focusHeading(ctx); } },
      nextLabel || t("common.next")) : null);
}

function focusHeading(ctx) {
  const heading = ctx.body.querySelector("h2");
  if (heading) heading.focus();
}

// ---------------------------------------------------------------------------------------- step 1
function sensorsStep(ctx) {
  const cards = ctx.sensors.map((sensor, i) => {
    const input = h("input", { name: `sensor-${i + 1}`, value: sensor.label, autocomplete: "off", maxlength: 80,
      placeholder: t("wizard.sensor_label_placeholder") });
    input.addEventListener("input", () => { sensor.label = input.value.trim(); saveSensors(ctx.sessionId, ctx.sensors); });
    const radios = SEGMENTS.map((seg) => {
      const radio = h("input", { type: "radio", name: `segment-${i + 1}`, value: seg, checked: sensor.segment === seg });
      radio.addEventListener("change", () => {
        sensor.segment = seg;
        ctx.sensors[1 - i].segment = SEGMENTS.find((s) => s !== seg);   // the other sensor takes the other segment
        saveSensors(ctx.sessionId, ctx.sensors);
        goTo(ctx, 1);
        ctx.body.querySelector(`input[name="segment-${i + 1}"][value="${seg}"]`).focus();
      });
      return h("label", { class: "radio" }, radio, label("segment", seg));
    });
    return h("div", { class: "card sensor" },
      h("h3", {}, t("wizard.sensor_n", { n: i + 1 })),
      field(t("wizard.sensor_label"), input, t("wizard.sensor_label_hint"))[0],
      h("fieldset", { class: "segment-choice" }, h("legend", {}, t("wizard.placed_on")), radios),
      h("p", { class: "hint" }, t(`wizard.placement.${sensor.segment}`)));
  });
  return h("div", {},
    h("h2", {}, t("wizard.step1_title")),
    h("p", {}, t("wizard.step1_lead")),
    h("div", { class: "columns" }, cards),
    navButtons(ctx, { next: 2 }));
}

// ---------------------------------------------------------------------------------------- step 2
function uploadStep(ctx) {
  ctx.zones = [];
  const groups = SEGMENTS.map((seg) => h("fieldset", { class: "card segment-group", "data-segment": seg },
    h("legend", {}, `${label("segment", seg)} — ${sensorOn(ctx.sensors, seg)}`),
    h("div", { class: "zones" }, ZONE_ROLES.map((role) => dropZone(ctx, seg, role)))));
  const other = h("fieldset", { class: "card segment-group other" },
    h("legend", {}, t("wizard.other_files")), h("div", { class: "zones" }, dropZone(ctx, null, null)));
  const wrap = h("div", {},
    h("h2", {}, t("wizard.step2_title")),
    h("p", {}, t("wizard.step2_lead")),
    canEdit() ? h("p", { class: "record-link" }, h("a", { href: `#/sessions/${ctx.sessionId}/record` }, t("record.link"))) : null,
    groups, other, ctx.ingestionArea, ctx.splitArea,
    navButtons(ctx, { back: 1, next: 3 }));
  renderIngestion(ctx, ctx.session.ingestion);
  return wrap;
}

/** The zone ("segment/role") a stored recording belongs in: the one it was uploaded to, else the one the server's
 * check recognised it as (`ingestion.recognised`, by file name: a bulk drop on "other files" fills the zones; a
 * continuous recording the check split is the segment's "whole protocol"), else null ("other files"). */
function zoneOf(ctx, rec) {
  if (rec.segment && rec.role) return `${rec.segment}/${rec.role}`;
  const ingestion = ctx.session.ingestion || {};
  const found = (ingestion.recognised || {})[rec.file_name];
  if (!found || !SEGMENTS.includes(found.segment)) return null;
  const split = (ingestion.splits || {})[found.segment];
  if (split && split.file === rec.file_name) return `${found.segment}/continuous`;
  return ROLES.includes(found.role) ? `${found.segment}/${found.role}` : null;
}

function zoneRecordings(ctx, segment, role) {
  const zoneKeys = new Set(SEGMENTS.flatMap((s) => ZONE_ROLES.map((r) => `${s}/${r}`)));
  return (ctx.session.recordings || []).filter((r) => {
    const key = zoneOf(ctx, r);
    return segment === null ? !zoneKeys.has(key) : key === `${segment}/${role}`;
  });
}

/** Whether `text` names `word` whole: not inside a longer file name ("a.csv" is not named by "data.csv" nor by
 * "a.csv.bak"): the characters either side are not those of a file name.  `label`: `word` is a MetaBase recording
 * label, which its files' names continue with "_" ("rec1" is named by "rec1_acc.csv"). */
export function namesWhole(text, word, label = false) {
  const escaped = word.replace(/[.*+?^${}()|[\]\\]/g, "\\$&");
  const after = label ? "($|_|[^\\w.-]|\\.(?![\\w-]))" : "($|[^\\w.-]|\\.(?![\\w-]))";
  return new RegExp(`(^|[^\\w.-])${escaped}${after}`, "u").test(text);
}

/** The file names of `recs` the session's failed check names in its error (the file it rejected, whole, or the
 * recording label a MetaBase group of files shares: the name before its first "_"), or []. */
function rejected(ctx, recs) {
  const ingestion = ctx.session.ingestion || {};
  if (ingestion.ok) return [];
  const said = [ingestion.error || "", ...Object.values(ingestion.error_message || {})].join("\n");
  const named = (name) => {
    const label = name.split("_")[0];
    return namesWhole(said, name) || (label !== name && label.length >= 12 && namesWhole(said, label, true));
  };
  return recs.map((r) => r.file_name).filter((name) => name && named(name));
}

function dropZone(ctx, segment, role) {
  const title = segment ? label("recording", role) : t("wizard.other_files_title");
  const hint = segment ? t(`wizard.role_hint.${role}`) : t("wizard.other_files_hint");
  const inputId = `file-${segment || "other"}-${role || "any"}`;
  const input = h("input", { type: "file", multiple: true, accept: ".csv,.xlsx,.json,.zip,.h5", id: inputId, class: "visually-hidden",
    tabindex: "-1", "aria-hidden": "true" });
  const list = h("ul", { class: "files" });
  const status = h("div", { class: "zone-status", role: "status" });
  const macNote = h("div", { class: "zone-mac" });
  const showMacWarning = (recs) => {
    const text = macWarning(ctx, segment, recs);
    const shown = macNote.firstChild ? macNote.firstChild.textContent : null;
    if (text === shown) return;          // unchanged: not announced again
    clear(macNote);
    if (text) macNote.append(h("div", { class: "notice warning mac-warning", role: "alert" }, text));
  };
  const choose = h("button", { type: "button", class: "secondary small" }, t("wizard.choose_files"));
  choose.setAttribute("aria-label", `${t("wizard.choose_files")}: ${segment ? `${sensorName(segment)}, ` : ""}${title}`);
  const zone = h("div", { class: "zone", "data-segment": segment || "", "data-role": role || "" },
    h("h3", {}, title), h("p", { class: "hint" }, hint), list,
    h("div", { class: "zone-actions" }, choose, h("span", { class: "drop-hint" }, t("wizard.or_drop"))),
    input, status, macNote);
  const refreshList = () => {
    clear(list);
    const recs = zoneRecordings(ctx, segment, role);
    const refused = rejected(ctx, recs);
    // green ("filled") only for files the check did not reject; a rejected file turns the zone red and says so
    zone.classList.toggle("filled", recs.length > 0 && !refused.length);
    zone.classList.toggle("rejected", refused.length > 0);
    zone.dataset.state = refused.length ? "rejected" : recs.length ? "filled" : "empty";
    if (refused.length) {
      clear(status).append(h("div", { class: "notice error rejected-note", role: "alert" },
        t("wizard.file_rejected", { name: refused.join(", ") })));
    } else if (status.querySelector(".rejected-note")) {
      clear(status);
    }
    for (const rec of recs) {
      const remove = canEdit() ? h("button", { type: "button", class: "link danger",
        "aria-label": t("wizard.remove_file", { name: rec.file_name }) }, "✕") : h("span");
      remove.addEventListener("click", async () => {
        remove.disabled = true;
        try {
          await api("DELETE", `/sessions/${ctx.sessionId}/recordings/${rec.id}`);
          await reloadSession(ctx);
        } catch (err) {
          clear(status).append(alertBox(errorText(err)));
          remove.disabled = false;
        }
      });
      const stream = /_(Accelerometer|Gyroscope|Magnetometer)_/.exec(rec.file_name || "");   // a MetaBase stream
      list.append(h("li", {}, h("span", { class: "file-name", title: rec.file_name }, rec.file_name),
        stream ? h("span", { class: "tag" }, t(`stream.${stream[1]}`)) : null,
        segment && !(rec.segment && rec.role) ? h("span", { class: "tag recognised" }, t("wizard.recognised_tag")) : null,
        segment ? null : kneeTag(ctx, rec),
        h("span", { class: "file-size" }, bytes(rec.size_bytes)), remove));
    }
    if (!segment) {   // files of a session of both knees: the zones are one knee's, so they stay here, and say so
      const knees = recs.filter((rec) => kneeTag(ctx, rec)).length;
      const note = zone.querySelector(".knee-files-note");
      if (note) note.remove();
      if (knees) list.after(h("p", { class: "hint knee-files-note" }, t("wizard.knee_files_here", { n: knees })));
    }
    showMacWarning(recs);
  };
  if (!canEdit()) {   // read-only: the zone lists its files, nothing more
    zone.querySelector(".zone-actions").remove();
    input.remove();
  }
  ctx.zones.push(refreshList);
  refreshList();

  const send = async (files) => {
    if (!files.length) return;
    const form = new FormData();
    for (const f of files) form.append("files", f, f.name);
    if (segment) {
      form.append("segment", segment);
      form.append("role", role);
    }
    const bar = h("progress", { max: "1", value: "0", "aria-label": t("wizard.uploading") });
    clear(status).append(h("span", {}, t("wizard.uploading_n", { n: files.length })), bar);
    zone.classList.add("busy");
    choose.disabled = true;
    try {
      const answer = await upload(`/sessions/${ctx.sessionId}/recordings`, form, (f) => { bar.value = f; });
      clear(status);
      await reloadSession(ctx, answer.ingestion);
      // "saved" only when the check rejected none of them (refreshList then showed the refusal instead)
      if (!zone.classList.contains("rejected")) {
        clear(status).append(h("span", { class: "ok" }, t("wizard.uploaded_n", { n: (answer.recordings || []).length })));
      }
    } catch (err) {
      clear(status).append(alertBox(errorText(err)));
      showMacWarning(zoneRecordings(ctx, segment, role).map((rec) => rec.file_name || ""));   // nothing stored
    } finally {
      zone.classList.remove("busy");
      choose.disabled = false;
      input.value = "";
    }
  };
  choose.addEventListener("click", () => input.click());
  input.addEventListener("change", () => send([...input.files]));
  zone.addEventListener("dragover", (e) => { e.preventDefault(); e.dataTransfer.dropEffect = "copy"; zone.classList.add("dragover"); });
  zone.addEventListener("dragleave", () => zone.classList.remove("dragover"));
  zone.addEventListener("drop", (e) => {
    e.preventDefault();
    zone.classList.remove("dragover");
    send([...(e.dataTransfer.files || [])]);
  });
  return zone;
}

async function reloadSession(ctx, ingestion) {
  ctx.session = await api("GET", `/sessions/${ctx.sessionId}`);
  if (ctx.badge) {   // the badge follows the files (not "no files" after uploads)
    const badge = statusBadge(ctx.session.status);
    ctx.badge.replaceWith(badge);
    ctx.badge = badge;
  }
  for (const refresh of ctx.zones || []) refresh();
  renderIngestion(ctx, ingestion || ctx.session.ingestion);
}

/** A sentence of the check in the UI's language: `texts` ({lang: text}) from the server, else `english`. */
function inLanguage(texts, english) {
  return (texts && texts[lang()]) || english;
}

/** The check's error sentence in the UI's language. */
function ingestionError(ingestion) {
  return inLanguage(ingestion.error_message, ingestion.error);
}

/** The ingestion check of the session (ok / error sentence / messages), then the split of continuous recordings. */
function renderIngestion(ctx, ingestion) {
  renderSplit(ctx, ingestion);
  const area = ctx.ingestionArea;
  clear(area);
  if (!(ctx.session.recordings || []).length) {
    area.append(h("div", { class: "card ingestion-box empty" }, h("h3", {}, t("wizard.check_title")),
      h("p", {}, t("wizard.check_none"))));
    return;
  }
  if (!ingestion) return;
  const box = h("div", { class: `card ingestion-box ${ingestion.ok ? "ok" : "bad"}`, id: "ingestion" },
    h("h3", {}, t("wizard.check_title")),
    ingestion.ok ? h("p", { class: "ok-line" }, t("wizard.check_ok"))
      : h("div", { class: "notice error", role: "alert" }, h("strong", {}, t("wizard.check_error")), " ",
        h("span", { class: "ingestion-error" }, ingestionError(ingestion) || t("error.unknown"))));
  const english = ingestion.messages || [];
  const texts = ingestion.message_texts || [];
  const messages = english.map((m, i) => inLanguage(texts[i], m));
  if (messages.length) {
    box.append(h("details", { open: true }, h("summary", {}, t("wizard.check_messages", { n: messages.length })),
      h("ul", { class: "messages" }, messages.map((m) => h("li", {}, m)))));
  }
  area.append(box);
}

// ---------------------------------------------------------------------- the split of continuous recordings
const SVG_NS = "http://www.w3.org/2000/svg";
const PART_COLOURS = { mag_calibration: "#c9d8f0", standing: "#cfe8cf", lying: "#f3e2bf", task: "#ead0e6" };
const TRACE_W = 1000;
const TRACE_H = 120;

function svg(tag, attrs = {}, ...children) {
  const el = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== null && v !== undefined) el.setAttribute(k, String(v));
  for (const c of children) el.append(c);
  return el;
}

/** A small square of the colour `role` has on the trace. */
function swatch(role) {
  return svg("svg", { width: 12, height: 12, "aria-hidden": "true", class: "swatch" },
    svg("rect", { x: 0, y: 0, width: 12, height: 12, fill: PART_COLOURS[role], stroke: "#888" }));
}

/** Seconds shown with one decimal (what the inputs and the server take). */
function sec(x) {
  return Math.round(x * 10) / 10;
}

/** The check's key of a sensor ("thigh", or "left_thigh" for a knee of a four-sensor session) in words. */
function sensorName(key) {
  const m = /^(left|right)_(thigh|shank)$/.exec(key);
  return m ? `${label("side", m[1])} · ${label("segment", m[2])}` : label("segment", key);
}

/** A tag naming the knee, sensor and recording the check recognised `rec` as in a session of both knees (the zones
 * are one knee's, so such a file is listed under "other files"), or null. */
function kneeTag(ctx, rec) {
  const found = ((ctx.session.ingestion || {}).recognised || {})[rec.file_name];
  if (!found || !/^(left|right)_/.test(found.segment || "")) return null;
  const role = found.role ? ` · ${label("recording", found.role)}` : "";
  return h("span", { class: "tag recognised knee" }, `${sensorName(found.segment)}${role}`);
}

/** Thigh before shank (the order of SEGMENTS), the left knee's before the right's. */
function bySensor(a, b) {
  const order = (k) => {
    const m = /^(?:(left|right)_)?(thigh|shank)$/.exec(k) || [];
    return (m[1] === "right" ? 10 : 0) + SEGMENTS.indexOf(m[2]);
  };
  return order(a) - order(b);
}

/** Step 2's split editor: one card per sensor whose continuous recording the check cut (`ingestion.splits`). */
function renderSplit(ctx, ingestion) {
  const area = ctx.splitArea;
  if (!area) return;
  clear(area);
  const splits = (ingestion && ingestion.splits) || {};
  // a sensor's key: "thigh"/"shank", or "left_thigh"… for a four-sensor session (the check keys them by knee)
  const segments = Object.keys(splits).filter((s) => splits[s] && splits[s].spans_s).sort(bySensor);
  if (!segments.length) return;
  // the cuts being edited, per segment: [start_s, end_s] per part, starting from what the check used
  const edit = Object.fromEntries(segments.map((s) => [s, Object.fromEntries(
    Object.entries(splits[s].spans_s).map(([role, span]) => [role, [Number(span[0]), Number(span[1])]]))]));
  const confirmed = ingestion.confirmed_split || (ctx.session.ingestion || {}).confirmed_split || null;
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const cards = segments.map((seg) => splitCard(ctx, seg, splits[seg], edit[seg], message));
  const confirm = h("button", { type: "button", class: "primary", id: "split-confirm", disabled: !canEdit() },
    t("wizard.split_confirm"));
  const reset = confirmed ? h("button", { type: "button", class: "secondary", id: "split-reset", disabled: !canEdit() },
    t("wizard.split_reset")) : null;
  const store = async (body, button) => {
    clear(message);
    const bad = body ? badSpan(segments, splits, body) : null;
    if (bad) {
      message.append(alertBox(bad));
      return;
    }
    button.disabled = true;
    try {
      const answer = await api("PUT", `/sessions/${ctx.sessionId}/split`, { json: { split: body } });
      await reloadSession(ctx, answer);
      ctx.splitArea.querySelector(".split-state").focus();
    } catch (err) {
      message.append(alertBox(errorText(err)));
      button.disabled = false;
    }
  };
  confirm.addEventListener("click", () => store(edit, confirm));
  if (reset) reset.addEventListener("click", () => store(null, reset));
  area.append(h("section", { class: "card split-editor", id: "split", "aria-labelledby": "split-title" },
    h("h3", { id: "split-title" }, t("wizard.split_title")),
    h("p", { class: "hint" }, t("wizard.split_lead")),
    h("p", { class: `split-state notice ${confirmed ? "info" : "warning"}`, role: "status", tabindex: "-1",
      "data-confirmed": confirmed ? "yes" : "no" }, t(confirmed ? "wizard.split_confirmed" : "wizard.split_automatic")),
    cards, message, h("div", { class: "actions" }, confirm, reset)));
}

/** The sentence for the first cut that is not 0 ≤ start < end ≤ the recording's length, or null. */
function badSpan(segments, splits, body) {
  for (const seg of segments) {
    const duration = Number(splits[seg].duration_s) || Infinity;
    for (const [role, [a, b]] of Object.entries(body[seg] || {})) {
      if (!(Number.isFinite(a) && Number.isFinite(b) && a >= 0 && a < b && b <= duration + 0.05)) {
        return t("wizard.split_bad", { segment: sensorName(seg), part: label("recording", role),
          duration: num(duration, 1) });
      }
    }
  }
  return null;
}

/** One sensor's trace with its parts, draggable cuts and the typed seconds of each part. */
function splitCard(ctx, segment, split, spans, message) {
  const duration = Number(split.duration_s) || Math.max(...Object.values(spans).map((p) => p[1]), 1);
  const trace = split.trace || [];
  const hz = Number(split.trace_hz) || 1;
  const top = Math.max(...trace, 1e-6);
  const x = (s) => (s / duration) * TRACE_W;
  const points = trace.map((v, i) => `${x(i / hz).toFixed(1)},${(TRACE_H - 4 - (v / top) * (TRACE_H - 12)).toFixed(1)}`);
  const bands = svg("g", { class: "parts" });
  const handles = svg("g", { class: "cuts" });
  const plot = svg("svg", { viewBox: `0 0 ${TRACE_W} ${TRACE_H}`, preserveAspectRatio: "none", class: "split-trace",
    width: "100%", height: TRACE_H, role: "img", "data-segment": segment,
    "aria-label": t("wizard.split_trace", { segment: sensorName(segment), seconds: num(duration, 0) }) },
  svg("rect", { x: 0, y: 0, width: TRACE_W, height: TRACE_H, fill: "#fafafa" }), bands,
  svg("polyline", { points: points.join(" "), fill: "none", stroke: "#333", "stroke-width": 1.2,
    "vector-effect": "non-scaling-stroke" }), handles);
  const inputs = {};
  const rows = ROLES.filter((role) => spans[role]).map((role) => {
    const from = h("input", { type: "number", step: "0.1", min: "0", max: String(sec(duration)), inputmode: "decimal",
      name: `split-${segment}-${role}-from`, value: String(sec(spans[role][0])), disabled: !canEdit(),
      "aria-label": t("wizard.split_from_of", { segment: sensorName(segment), part: label("recording", role) }) });
    const to = h("input", { type: "number", step: "0.1", min: "0", max: String(sec(duration)), inputmode: "decimal",
      name: `split-${segment}-${role}-to`, value: String(sec(spans[role][1])), disabled: !canEdit(),
      "aria-label": t("wizard.split_to_of", { segment: sensorName(segment), part: label("recording", role) }) });
    inputs[role] = [from, to];
    [from, to].forEach((input, k) => input.addEventListener("input", () => {
      const value = Number(input.value);
      clear(message);   // a refusal of the earlier values no longer applies
      if (input.value !== "" && Number.isFinite(value)) {
        spans[role][k] = value;
        draw();
      }
    }));
    return h("tr", { "data-role": role },
      h("th", { scope: "row" }, swatch(role), " ", label("recording", role)),
      h("td", {}, from), h("td", {}, to));
  });
  const draw = () => {
    while (bands.firstChild) bands.firstChild.remove();
    while (handles.firstChild) handles.firstChild.remove();
    for (const role of ROLES.filter((r) => spans[r])) {
      const [a, b] = spans[role];
      bands.append(svg("rect", { x: x(a).toFixed(1), y: 0, width: Math.max(0, x(b) - x(a)).toFixed(1), height: TRACE_H,
        fill: PART_COLOURS[role], "data-role": role }, svg("title", {}, label("recording", role))));
      [0, 1].forEach((k) => handles.append(cutHandle(role, k)));
    }
  };
  // a cut: a wide invisible grip around a thin line; dragged with the pointer, or moved with the arrow keys
  const cutHandle = (role, k) => {
    const at = x(spans[role][k]);
    const name = t(k === 0 ? "wizard.split_from_of" : "wizard.split_to_of",
      { segment: sensorName(segment), part: label("recording", role) });
    const grip = svg("g", { class: "cut", tabindex: canEdit() ? "0" : null, role: "slider", "aria-label": name,
      "aria-valuemin": 0, "aria-valuemax": sec(duration), "aria-valuenow": sec(spans[role][k]),
      "data-role": role, "data-edge": k === 0 ? "from" : "to", cursor: "ew-resize" },
    svg("rect", { x: (at - 8).toFixed(1), y: 0, width: 16, height: TRACE_H, fill: "transparent" }),
    svg("line", { x1: at.toFixed(1), x2: at.toFixed(1), y1: 0, y2: TRACE_H, stroke: "#1d4e89", "stroke-width": 2,
      "vector-effect": "non-scaling-stroke" }));
    if (!canEdit()) return grip;
    const move = (seconds) => {
      spans[role][k] = sec(Math.min(duration, Math.max(0, seconds)));
      inputs[role][k].value = String(spans[role][k]);
      clear(message);
      draw();
    };
    grip.addEventListener("pointerdown", (e) => {
      e.preventDefault();
      const box = plot.getBoundingClientRect();
      const onMove = (ev) => move(((ev.clientX - box.left) / box.width) * duration);
      const onUp = () => {
        window.removeEventListener("pointermove", onMove);
        window.removeEventListener("pointerup", onUp);
      };
      window.addEventListener("pointermove", onMove);
      window.addEventListener("pointerup", onUp);
    });
    grip.addEventListener("keydown", (e) => {
      const step = e.shiftKey ? 5 : 0.5;
      if (e.key !== "ArrowLeft" && e.key !== "ArrowRight") return;
      e.preventDefault();
      move(spans[role][k] + (e.key === "ArrowLeft" ? -step : step));
      const again = handles.querySelector(`.cut[data-role="${role}"][data-edge="${k === 0 ? "from" : "to"}"]`);
      if (again) again.focus();
    });
    return grip;
  };
  draw();
  return h("div", { class: "split-sensor", "data-segment": segment },
    h("h4", {}, sensorName(segment), " — ", h("span", { class: "file-name" }, split.file || "")),
    plot,
    h("table", { class: "data split-table" },
      h("thead", {}, h("tr", {}, h("th", { scope: "col" }, t("wizard.split_part")),
        h("th", { scope: "col" }, t("wizard.split_from")), h("th", { scope: "col" }, t("wizard.split_to")))),
      h("tbody", {}, rows)));
}

// ---------------------------------------------------------------------------------------- step 3
function processStep(ctx) {
  const ingestion = ctx.session.ingestion || { ok: false, messages: [], error: null };
  // both menus come from GET /options (app/choices.py): the filters of the estimator registry, the reports' languages
  const filter = h("select", { name: "filter" });
  const language = h("select", { name: "lang" });
  const headingSelect = h("select", { name: "heading" });
  // the side override (as `chakamo process --side`): empty = the patient's side, checked against the files'
  const sideSelect = h("select", { name: "side" });
  // the involved knee of a session of both knees (as `chakamo process --involved`): empty = the patient's side
  const involvedSelect = h("select", { name: "involved" });
  // the sensor-to-segment calibration and the knee-angle convention (as `chakamo process --calibration / --angles`)
  const calibrationSelect = h("select", { name: "calibration" });
  const conventionSelect = h("select", { name: "angle_convention" });
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  // enabled once GET /options has filled the menus: a click before that sent no filter (422, seen under load)
  const processButton = h("button", { type: "submit", class: "primary", disabled: true }, t("wizard.process"));
  const form = h("form", { class: "card form-grid process-form" },
    field(t("wizard.filter"), filter, t("wizard.filter_hint"))[0],
    field(t("wizard.report_language"), language, t("wizard.report_language_hint"))[0],
    field(t("wizard.heading"), headingSelect, t("wizard.heading_hint"))[0],
    field(t("wizard.side"), sideSelect, t("wizard.side_hint"))[0],
    field(t("wizard.involved"), involvedSelect, t("wizard.involved_hint"))[0],
    field(t("wizard.calibration"), calibrationSelect, t("wizard.calibration_hint"))[0],
    field(t("wizard.angle_convention"), conventionSelect, t("wizard.angle_convention_hint"))[0],
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, processButton));
  if (!ingestion.ok) {
    message.append(alertBox(ingestion.error
      ? t("wizard.cannot_process", { error: ingestionError(ingestion) })
      : t("wizard.cannot_process_empty")));
  } else if (Object.keys(ingestion.splits || {}).length && !ingestion.confirmed_split) {
    message.append(h("div", { class: "notice warning", role: "status", id: "split-unconfirmed" },
      t("wizard.split_unconfirmed")));
  }
  options().then((opts) => {
    fillSelect(filter, "filter", opts.filters);
    fillSelect(language, "lang", opts.languages, lang());
    fillSelect(headingSelect, "heading", opts.headings);
    fillSelect(sideSelect, "side", opts.sides);
    sideSelect.prepend(h("option", { value: "", selected: true }, t("wizard.side_patient")));
    sideSelect.value = "";
    fillSelect(involvedSelect, "side", opts.sides);
    involvedSelect.prepend(h("option", { value: "", selected: true },
      t("wizard.involved_patient", { side: label("side", ctx.patient.side) })));
    involvedSelect.value = "";
    fillSelect(calibrationSelect, "calibration", opts.calibrations);
    fillSelect(conventionSelect, "angle_convention", opts.angle_conventions);
    processButton.disabled = !ingestion.ok || !canEdit() || Boolean(ctx.activeJob);
  }).catch((err) => message.append(alertBox(errorText(err))));
  ctx.progressArea = h("div", { class: "progress-area" });
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    processButton.disabled = true;
    try {
      const answer = await api("POST", `/sessions/${ctx.sessionId}/process`, { json: { filter: filter.value, lang: language.value, heading: headingSelect.value,
        side: sideSelect.value || null, involved: involvedSelect.value || null,
        calibration: calibrationSelect.value, angle_convention: conventionSelect.value } });
      showProgress(ctx, answer.job_id);
    } catch (err) {
      message.append(alertBox(errorText(err)));
      processButton.disabled = false;
    }
  });
  return h("div", {},
    h("h2", {}, t("wizard.step3_title")),
    h("p", {}, t("wizard.step3_lead")),
    form, ctx.progressArea,
    navButtons(ctx, { back: 2 }));
}

// the artefacts the job renders, by the file name its stage carries ("report.pdf es" → the PDF report in Spanish;
// app/pipeline/render.py names these stages)
const ARTEFACT_STAGES = { "report.pdf": "stage.report_pdf", "report.html": "stage.report_html",
  "scene.viser": "stage.scene", "angles.xlsx": "stage.workbooks", "quaternions.xlsx": "stage.workbooks" };

/** Language `code` named in the UI's language ("Spanish" in English, "espanhol" in Portuguese), not in its own. */
function languageName(code) {
  try {
    return new Intl.DisplayNames([lang()], { type: "language" }).of(code) || code;
  } catch {
    return code;
  }
}

/** The stage of a job as a sentence ("orientation thigh" → "Orientation of the thigh sensor"; "report.pdf es" →
 * "Writing the PDF report (Spanish)"): never a file name; a stage this version does not know reads "Processing". */
export function stageText(stage) {
  if (!stage) return "";
  const words = String(stage).trim().split(/\s+/);
  // a session of both knees: "left orientation thigh" → "Left · Orientation of the thigh sensor"
  if (words.length > 1 && (words[0] === "left" || words[0] === "right")) {
    return `${label("side", words[0])} · ${stageText(words.slice(1).join(" "))}`;
  }
  if (ARTEFACT_STAGES[words[0]]) {
    const language = words[1] ? languageName(words[1]) : "";
    const text = t(ARTEFACT_STAGES[words[0]]);
    return language ? `${text} (${language})` : text;
  }
  for (const key of [`stage.${words.join("_")}`, `stage.${words[0]}`]) {
    const text = t(key);
    if (text !== key) return text;
  }
  return t("wizard.processing");
}

function showProgress(ctx, jobId) {
  ctx.activeJob = jobId;
  if (ctx.step !== 3) {
    goTo(ctx, 3);          // which shows the progress of ctx.activeJob
    return;
  }
  const form = ctx.body.querySelector("form.process-form");
  if (form) form.querySelector("button[type=submit]").disabled = true;
  const bar = h("progress", { id: "job-progress", max: "1", value: "0", "aria-labelledby": "job-progress-label",
    "data-job-id": String(jobId) });
  const stage = h("p", { class: "stage", "aria-live": "polite" });
  const pct = h("span", { class: "pct" }, "0 %");
  const outcome = h("div", { class: "outcome" });
  const box = h("div", { class: "card job", id: "job", "data-status": "queued" },
    h("h3", { id: "job-progress-label" }, t("wizard.processing")), h("div", { class: "bar-row" }, bar, pct), stage, outcome);
  clear(ctx.progressArea).append(box);
  box.scrollIntoView({ block: "nearest" });

  const render = (job) => {
    const fraction = Math.max(0, Math.min(1, Number(job.progress) || 0));
    bar.value = job.status === "done" ? 1 : fraction;
    pct.textContent = `${num(100 * bar.value, 0)} %`;
    box.dataset.status = job.status;
    stage.textContent = job.status === "queued" ? t("wizard.queued") : stageText(job.stage);
    if (job.status === "done" || job.status === "failed") {
      ctx.activeJob = null;
      if (form && form.isConnected) form.querySelector("button[type=submit]").disabled = !canEdit();
    }
    if (job.status === "done") {
      stage.textContent = t("wizard.done");
      const go = h("a", { href: `#/sessions/${ctx.sessionId}?analysis_id=${job.analysis_id ?? ""}`, class: "button-link primary",
        id: "see-results" }, t("wizard.see_results"));
      clear(outcome).append(go);
      go.focus();
    }
    if (job.status === "failed") {
      append(clear(outcome), [
        h("div", { class: "notice error", role: "alert" }, h("strong", {}, t("wizard.failed")), " ",
          (job.error_message && job.error_message[lang()]) || job.error || t("error.unknown")),
        (job.log || []).length ? h("details", {}, h("summary", {}, t("wizard.job_log")),
          h("pre", { class: "log" }, (job.log || []).join("\n"))) : null]);
    }
  };
  const ended = (job) => job.status === "done" || job.status === "failed";

  let failures = 0;
  const poll = async () => {
    if (!box.isConnected) return;          // the user left the page: stop polling
    let job;
    try {
      job = await api("GET", `/jobs/${jobId}`);
      failures = 0;
    } catch (err) {
      failures += 1;
      if (err.status === 401 || err.status === 404 || failures >= 20) {
        clear(outcome).append(alertBox(errorText(err)));
        return;
      }
      setTimeout(poll, POLL_MS * 3);
      return;
    }
    if (!box.isConnected) return;
    render(job);
    if (!ended(job)) setTimeout(poll, POLL_MS);
  };
  followStream(box, jobId, render, ended, poll);
}

const STREAM_QUIET_MS = 4000;   // no news of the job this long after the stream opened: its state is read once

/** The job's news from the server-sent event stream (GET /events) into `render`, until it ends (then its full
 *  state, GET /jobs/{id}, once) or the box leaves the page; `fallback()` (polling, which retries a failed read)
 *  takes over if the stream cannot be opened, breaks twice in a row without coming back, or ends, and if a read of
 *  GET /jobs/{id} fails (a network blip, 503, a restart: also the one read at the end, which would otherwise leave
 *  the bar standing).  Every (re)connection that brings no news of the job within STREAM_QUIET_MS reads its state
 *  once: the server ends each stream after 10 minutes and a new one only looks back 5 s, so a job that ended while
 *  the page reconnected is found this way.  The box counts the events it received (data-events) and says which way
 *  the news came (data-via). */
function followStream(box, jobId, render, ended, fallback) {
  if (typeof EventSource === "undefined") {
    box.dataset.via = "polling";
    fallback();
    return;
  }
  const source = new EventSource(apiUrl("/events"), { withCredentials: true });
  box.dataset.via = "stream";
  box.dataset.events = "0";
  let opened = false;
  let errors = 0;
  let heard = false;
  let done = false;
  let polling = false;
  const stop = () => { done = true; source.close(); clearInterval(watch); };
  const toPolling = () => {             // at most once, also after stop(): the end's read can fail after it
    if (polling) return;
    polling = true;
    stop();
    box.dataset.via = "polling";
    fallback();
  };
  const readOnce = async () => {            // the job itself: with its error text, log and analysis
    try {
      const job = await api("GET", `/jobs/${jobId}`);
      if (box.isConnected) render(job);
      return job;
    } catch (_) {
      toPolling();
      return null;
    }
  };
  const finish = () => { stop(); readOnce(); };
  const watch = setInterval(() => { if (!box.isConnected) stop(); }, 2000);
  source.addEventListener("open", () => {
    opened = true;
    errors = 0;
    heard = false;                          // a reconnection: news of the job from this stream, else one read
    setTimeout(async () => {
      if (heard || done || !box.isConnected) return;
      const job = await readOnce();
      if (job && ended(job)) stop();
    }, STREAM_QUIET_MS);
  });
  source.addEventListener("job", (event) => {
    if (done) return;
    if (!box.isConnected) { stop(); return; }
    let job;
    try { job = JSON.parse(event.data); } catch (_) { return; }
    if (Number(job.id) !== Number(jobId)) return;      // another of the clinic's jobs
    heard = true;
    errors = 0;
    box.dataset.events = String(Number(box.dataset.events) + 1);
    if (ended(job)) finish();
    else render(job);
  });
  source.addEventListener("end", toPolling);  // the login closed or the token expired: polling says so plainly
  source.addEventListener("error", () => {
    errors += 1;
    if (!opened || source.readyState === EventSource.CLOSED || errors >= 2) toPolling();
  });
}
