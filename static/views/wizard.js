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
// - Progress: GET /jobs/{id} every 300 ms while the page is shown; <progress> carries the fraction.

import { api, upload } from "../api.js";
import { h, append, clear, field, alertBox, errorText, date, bytes, label, num } from "../dom.js";
import { t, lang } from "../i18n.js";
import { options, fillSelect } from "../options.js";
import { patientTitle, statusBadge } from "./patients.js";
import { canEdit } from "../app.js";

export const SEGMENTS = ["thigh", "shank"];
export const ROLES = ["mag_calibration", "standing", "lying", "task"];
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
  const hasResults = (session.analyses || []).length > 0;
  append(clear(ctx.section), [
    h("nav", { class: "crumbs", "aria-label": t("common.breadcrumbs") },
      h("a", { href: "#/patients" }, t("nav.patients")), " › ",
      h("a", { href: `#/patients/${patient.id}` }, patientTitle(patient))),
    h("div", { class: "title-row" },
      h("h1", {}, t("wizard.title_session", { date: date(session.date) })),
      statusBadge(session.status),
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
    h("div", { class: "zones" }, ROLES.map((role) => dropZone(ctx, seg, role)))));
  const other = h("fieldset", { class: "card segment-group other" },
    h("legend", {}, t("wizard.other_files")), h("div", { class: "zones" }, dropZone(ctx, null, null)));
  const wrap = h("div", {},
    h("h2", {}, t("wizard.step2_title")),
    h("p", {}, t("wizard.step2_lead")),
    groups, other, ctx.ingestionArea,
    navButtons(ctx, { back: 1, next: 3 }));
  renderIngestion(ctx, ctx.session.ingestion);
  return wrap;
}

function zoneRecordings(ctx, segment, role) {
  const zoneKeys = new Set(SEGMENTS.flatMap((s) => ROLES.map((r) => `${s}/${r}`)));
  return (ctx.session.recordings || []).filter((r) => (segment === null
    ? !zoneKeys.has(`${r.segment}/${r.role}`)
    : r.segment === segment && r.role === role));
}

function dropZone(ctx, segment, role) {
  const title = segment ? label("recording", role) : t("wizard.other_files_title");
  const hint = segment ? t(`wizard.role_hint.${role}`) : t("wizard.other_files_hint");
  const inputId = `file-${segment || "other"}-${role || "any"}`;
  const input = h("input", { type: "file", multiple: true, accept: ".csv,.xlsx,.json", id: inputId, class: "visually-hidden",
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
  choose.setAttribute("aria-label", `${t("wizard.choose_files")}: ${segment ? `${label("segment", segment)}, ` : ""}${title}`);
  const zone = h("div", { class: "zone", "data-segment": segment || "", "data-role": role || "" },
    h("h3", {}, title), h("p", { class: "hint" }, hint), list,
    h("div", { class: "zone-actions" }, choose, h("span", { class: "drop-hint" }, t("wizard.or_drop"))),
    input, status, macNote);
  const refreshList = () => {
    clear(list);
    const recs = zoneRecordings(ctx, segment, role);
    zone.classList.toggle("filled", recs.length > 0);
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
        h("span", { class: "file-size" }, bytes(rec.size_bytes)), remove));
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
      clear(status).append(h("span", { class: "ok" }, t("wizard.uploaded_n", { n: (answer.recordings || []).length })));
      await reloadSession(ctx, answer.ingestion);
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
  for (const refresh of ctx.zones || []) refresh();
  renderIngestion(ctx, ingestion || ctx.session.ingestion);
}

/** The ingestion check of the session (ok / error sentence / messages). */
function renderIngestion(ctx, ingestion) {
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
        h("span", { class: "ingestion-error" }, ingestion.error || t("error.unknown"))));
  const messages = ingestion.messages || [];
  if (messages.length) {
    box.append(h("details", { open: true }, h("summary", {}, t("wizard.check_messages", { n: messages.length })),
      h("ul", { class: "messages" }, messages.map((m) => h("li", {}, m)))));
  }
  area.append(box);
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
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const processButton = h("button", { type: "submit", class: "primary", disabled: !ingestion.ok || !canEdit() },
    t("wizard.process"));
  const form = h("form", { class: "card form-grid process-form" },
    field(t("wizard.filter"), filter, t("wizard.filter_hint"))[0],
    field(t("wizard.report_language"), language, t("wizard.report_language_hint"))[0],
    field(t("wizard.heading"), headingSelect, t("wizard.heading_hint"))[0],
    field(t("wizard.side"), sideSelect, t("wizard.side_hint"))[0],
    field(t("wizard.involved"), involvedSelect, t("wizard.involved_hint"))[0],
    h("div", { class: "wide" }, message),
    h("div", { class: "actions wide" }, processButton));
  if (!ingestion.ok) {
    message.append(alertBox(ingestion.error
      ? t("wizard.cannot_process", { error: ingestion.error })
      : t("wizard.cannot_process_empty")));
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
  }).catch((err) => message.append(alertBox(errorText(err))));
  ctx.progressArea = h("div", { class: "progress-area" });
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    processButton.disabled = true;
    try {
      const answer = await api("POST", `/sessions/${ctx.sessionId}/process`, { json: { filter: filter.value, lang: language.value, heading: headingSelect.value,
        side: sideSelect.value || null, involved: involvedSelect.value || null } });
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

/** The stage of a job as a sentence ("orientation thigh" → "Orientation of the thigh sensor"). */
function stageText(stage) {
  if (!stage) return "";
  const words = String(stage).trim().split(/\s+/);
  // a session of both knees: "left orientation thigh" → "Left · Orientation of the thigh sensor"
  if (words.length > 1 && (words[0] === "left" || words[0] === "right")) {
    return `${label("side", words[0])} · ${stageText(words.slice(1).join(" "))}`;
  }
  for (const key of [`stage.${words.join("_")}`, `stage.${words[0]}`]) {
    const text = t(key);
    if (text !== key) return text;
  }
  return String(stage);
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
      return;
    }
    if (job.status === "failed") {
      append(clear(outcome), [
        h("div", { class: "notice error", role: "alert" }, h("strong", {}, t("wizard.failed")), " ",
          (job.error_message && job.error_message[lang()]) || job.error || t("error.unknown")),
        (job.log || []).length ? h("details", {}, h("summary", {}, t("wizard.job_log")),
          h("pre", { class: "log" }, (job.log || []).join("\n"))) : null]);
      return;
    }
    setTimeout(poll, POLL_MS);
  };
  poll();
}
