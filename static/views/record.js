// Recording mode: the protocol recorded straight from two MetaMotion sensors over Web Bluetooth
// (#/sessions/3/record), instead of exporting files from the vendor's app and dropping them in the wizard.
//
// 1 Sensors: connect two (the browser's chooser), each shown with firmware, battery and state and a button that
//   blinks its LED (which physical sensor is which); identify
//   which is on the thigh (the clinician moves the thigh: static/metawear/recorder.js), or swap by hand.
// 2 Steps: the protocol's four recordings, each from both sensors at once, with its live check (figure-eight:
//   sphere cells reached of those the pipeline needs; postures: still or moving, the seconds still and the still
//   window the pipeline needs; task: cycles counted, approximate; thresholds served by GET /options live_checks;
//   and the preview of the three knee angles — the reports' names, order and signs, the left leg mirrored —
//   static/metawear/preview.js, once both postures were recorded in this visit),
//   the samples received and lost, and the sensors' state (reconnecting after a drop).  Stopping a step
//   uploads it at once as MetaBase CSV files (segment and role fields); only an upload whose stored sha256
//   match the browser's clears the step's buffer (IndexedDB), so nothing unacknowledged is lost: a failed
//   upload stays to retry, also after a reload.  Starting a step that already has data (files on the server,
//   recorded here or dropped in the wizard; an unsent take in this browser) asks first, naming each and where
//   it came from; the browser's unsent take is dropped only then, and the server's files only once the new
//   take is acknowledged (until then the old files are the step's data).
//   Closing the page while a step records or waits to be sent asks first; leaving the view lets go of the sensors.
// 3 Processing is the wizard's (its step 3), linked once the four steps are stored.
// Everything the user reads is translated (record.* keys); the sensors' own errors are named by code.

import { api, upload } from "../api.js";
import { h, append, clear, alertBox, errorText, label, num } from "../dom.js";
import { t } from "../i18n.js";
import { canEdit } from "../app.js";
import { options } from "../options.js";
import { pickSensor, MetaWearSensor, bluetoothErrorCode } from "../metawear/device.js";
import { PacketStore } from "../metawear/store.js";
import { Recorder, STEPS, SEGMENTS, fileLabel } from "../metawear/recorder.js";
import { CELL_COUNT } from "../metawear/checks.js";
import { ANGLES } from "../charts.js";

const REFRESH_MS = 100;   // the live figures (the angle preview follows every animation frame: previewFrame)

async function send(sessionId, segment, role, files) {
  // files already stored with the same content (an earlier attempt answered after all) are not sent again
  const session = await api("GET", `/sessions/${sessionId}`);
  const have = new Map((session.recordings || []).map((r) => [r.file_name, r]));
  const missing = files.filter((f) => have.get(f.name)?.sha256 !== f.sha256);
  const recordings = files.map((f) => have.get(f.name)).filter((r) => r && !missing.some((m) => m.name === r.file_name));
  if (missing.length) {
    const form = new FormData();
    form.append("segment", segment);
    form.append("role", role);
    for (const f of missing) form.append("files", new Blob([f.text], { type: "text/csv" }), f.name);
    const answer = await upload(`/sessions/${sessionId}/recordings`, form);
    recordings.push(...answer.recordings);
  }
  return { recordings };
}

function sensorCard(sensor, segment, fail) {
  const i = sensor.info;
  // the sensor's LED blinks: which physical sensor this card is (before strapping it, or to check the assignment)
  const blink = h("button", { type: "button", class: "secondary blink", disabled: sensor.state !== "connected"
    && sensor.state !== "streaming" }, t("record.blink"));
  blink.addEventListener("click", () => sensor.blink().catch(fail));
  return h("li", { class: "card sensor", "data-segment": segment || null },
    h("h3", {}, segment ? `${label("segment", segment)} — ${i.name}` : i.name),
    h("p", {}, t("record.sensor_line", { serial: i.serial || "—", firmware: i.firmware || "—",
      battery: i.battery ? num(i.battery.chargePercent, 0) : "—" })),
    h("p", { class: "sensor-state", "data-state": sensor.state }, t(`record.state.${sensor.state}`)), blink);
}

// the angle preview's text of one angle (the live list's line and previewFrame's every-frame update): the
// reports' angle names (static/charts.js ANGLES, label "angle.*") and order, degrees with their clinical signs
function angleText(name, deg) {
  return t("record.preview_angle", { angle: label("angle", name), deg: deg === null ? "—" : num(deg, 0) });
}

function previewLine(angles) {
  return h("li", { class: "preview" }, h("span", { class: "preview-title" }, t("record.preview_title")), " ",
    ...ANGLES.flatMap((name, i) => [i ? " · " : "", h("span", { "data-angle": name }, angleText(name, angles?.[i] ?? null))]));
}

function liveLine(role, live, angles) {
  const preview = role === "task" ? previewLine(angles) : null;
  const stored = live.bufferError ? h("li", { class: "buffer-error" }, t("record.buffer_error")) : null;
  return [preview, stored, ...SEGMENTS.map((s) => {
    const l = live[s];
    const samples = t("record.samples", { acc: l.samples.acc, gyr: l.samples.gyr, mag: l.samples.mag });
    let check = "";
    if (role === "mag_calibration") {
      check = t("record.coverage", { cells: l.coverage.cells, total: CELL_COUNT, need: l.coverage.need });
    } else if (role === "task") check = t("record.cycles", { n: l.cycles });
    else check = t(l.still ? "record.still" : "record.moving", { s: num(l.stillS, 0), need: num(l.stillNeedS, 0) });
    const bad = l.bad ? h("span", { class: "bad-packets" }, ` · ${t("record.bad_packets", { n: l.bad })}`) : "";
    return h("li", { "data-segment": s }, `${label("segment", s)}: `, h("span", { class: "check" }, check),
      ` · ${samples}`, bad, ` · ${t(`record.state.${l.state}`)}`);
  })];
}

export function recordView(sessionId) {
  const section = h("section", { class: "view record" });
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const optionsMessage = h("div", { class: "options-message", "aria-live": "polite" });   // until the recorder exists
  const sensorsList = h("ul", { class: "sensors" });
  const identifyArea = h("div", { class: "identify" });
  const stepsList = h("ol", { class: "record-steps" });
  const done = h("p", { class: "record-done" });
  const state = { sensors: [], recorder: null, store: null, status: {}, active: null, busy: false };
  for (const role of STEPS) state.status[role] = "todo";

  section.append(h("h1", {}, t("record.title")), h("p", { class: "lead" }, t("record.lead")), optionsMessage, message);
  if (!canEdit()) {
    section.append(alertBox(t("record.read_only"), "info"));
    return section;
  }
  if (!navigator.bluetooth) {
    section.append(alertBox(t("record.no_bluetooth")));
    return section;
  }

  const fail = (err) => {
    // the recorder's own errors carry a code (translated here); the API's are ApiErrors with their sentence
    const bt = bluetoothErrorCode(err);      // the browser's Bluetooth errors (English DOMException messages)
    const key = bt ? `record.error.${bt}`
      : err && typeof err.code === "string" && err.status === undefined ? `record.error.${err.code}` : null;
    clear(message).append(alertBox(key && t(key) !== key ? t(key) : errorText(err)));
  };

  const connectButton = h("button", { type: "button", class: "connect" }, t("record.connect"));
  connectButton.addEventListener("click", async () => {
    clear(message);
    try {
      const device = await pickSensor();
      if (state.sensors.some((s) => s.device.id === device.id)) throw Object.assign(new Error(), { code: "same_sensor" });
      const sensor = new MetaWearSensor(device, { onState: () => draw() });
      state.sensors.push(sensor);
      draw();
      try {
        await sensor.connect();
      } catch (err) {
        // not usable: let it go, so that another (or the same, woken) sensor can be connected instead
        sensor.disconnect();
        state.sensors = state.sensors.filter((s) => s !== sensor);
        throw err;
      }
    } catch (err) {
      if (err && err.name === "NotFoundError") return;     // the chooser was closed
      fail(err);
    }
    draw();
  });

  const identifyButton = h("button", { type: "button", class: "identify" }, t("record.identify"));
  let identifying = false;
  identifyButton.addEventListener("click", async () => {
    clear(message).append(alertBox(t("record.move_thigh"), "info"));
    identifying = true;
    identifyButton.disabled = true;
    try {
      const [thigh, shank] = await state.recorder.identify(...state.sensors);
      state.recorder.attach("thigh", thigh);
      state.recorder.attach("shank", shank);
      clear(message);
    } catch (err) {
      fail(err);
    }
    identifying = false;
    draw();
  });

  const swapButton = h("button", { type: "button", class: "secondary swap" }, t("record.swap"));
  swapButton.addEventListener("click", () => {
    // steps already recorded keep the assignment they were recorded with: swapping now mixes thigh and shank
    // between steps (wrong angles, silently), so it is asked first, naming them
    const done = STEPS.filter((r) => ["stored", "unsent"].includes(state.status[r]));
    if (done.length && !window.confirm(t("record.swap_warning", {
      steps: done.map((r) => label("recording", r)).join(", ") }))) return;
    const { thigh, shank } = state.recorder.sensors;
    state.recorder.attach("thigh", shank);
    state.recorder.attach("shank", thigh);
    draw();
  });

  // what a new take of `role` replaces: the server's files for it and an unsent take kept in this browser
  async function replaced(role) {
    const session = await api("GET", `/sessions/${sessionId}`);
    const files = (session.recordings || []).filter((r) => r.role === role && SEGMENTS.includes(r.segment));
    const unsent = (await state.store.steps(sessionId)).includes(role);
    return { files, unsent };
  }

  function replaceQuestion(role, { files, unsent }) {
    const mine = (f) => SEGMENTS.some((s) => f.file_name.startsWith(fileLabel(role, s)));
    const names = (fs) => fs.map((f) => f.file_name).join(", ");
    const here = files.filter(mine);
    const dropped = files.filter((f) => !mine(f));
    return [t("record.replace.intro", { step: label("recording", role) }),
      here.length ? t("record.replace.recorded", { n: here.length, names: names(here) }) : null,
      dropped.length ? t("record.replace.uploaded", { n: dropped.length, names: names(dropped) }) : null,
      unsent ? t("record.replace.unsent") : null,
      t("record.replace.when")].filter(Boolean).join("\n");
  }

  async function startStep(role) {
    clear(message);
    state.busy = true;
    try {
      const old = await replaced(role);
      if ((old.files.length || old.unsent) && !window.confirm(replaceQuestion(role, old))) {
        state.busy = false;
        draw();
        return;
      }
      await state.recorder.start(role);      // drops the browser's unsent take of this step (agreed above)
      state.active = role;
      state.status[role] = "recording";
    } catch (err) {
      fail(err);
    }
    state.busy = false;
    draw();
  }

  // once a take is acknowledged, the step's other files on the server (earlier takes, files dropped in the
  // wizard for it; the clinician agreed when starting the take) are deleted: the new take replaces them
  async function deleteReplaced(role, kept) {
    const keep = new Set(kept.map((r) => r.id));
    const { files } = await replaced(role);
    for (const r of files) if (!keep.has(r.id)) await api("DELETE", `/sessions/${sessionId}/recordings/${r.id}`);
  }

  async function finish(role, action) {
    clear(message);
    state.busy = true;
    state.status[role] = "uploading";
    draw();
    try {
      const answer = await action();
      state.status[role] = "stored";
      state.lost = { ...(state.lost || {}), [role]: answer.lost };
      // the take is stored and its buffer cleared: a failed deletion is said, the take stays stored
      await deleteReplaced(role, answer.recordings).catch(fail);
    } catch (err) {
      state.status[role] = "unsent";
      fail(err);
    }
    state.active = null;
    state.busy = false;
    draw();
  }

  function stepItem(role) {
    const status = state.status[role];
    const buttons = [];
    const ready = Boolean(state.recorder?.sensors.thigh && state.recorder?.sensors.shank);
    if (status === "recording") {
      buttons.push(h("button", { type: "button", class: "stop", onclick: () => finish(role, () => state.recorder.stop()) },
        t("record.stop")));
    } else if (status === "unsent") {
      buttons.push(h("button", { type: "button", class: "retry", disabled: state.busy || !state.recorder,
        onclick: () => finish(role, () => state.recorder.upload(role)) }, t("record.retry")));
    }
    if (status !== "recording" && status !== "uploading") {
      buttons.push(h("button", { type: "button", class: status === "todo" ? "start" : "secondary redo",
        disabled: !ready || state.busy || Boolean(state.active), onclick: () => startStep(role) },
      t(status === "todo" ? "record.start" : "record.redo")));
    }
    const live = status === "recording" ? state.recorder.live() : null;
    const lost = state.lost?.[role];
    return h("li", { class: "card record-step", "data-role": role, "data-status": status },
      h("h3", {}, label("recording", role)),
      h("p", { class: "hint" }, t(`wizard.role_hint.${role}`)),
      h("p", { class: "step-status" }, t(`record.status.${status}`),
        lost ? ` · ${t("record.lost", { thigh: lost.thigh, shank: lost.shank })}` : ""),
      live ? h("ul", { class: "live" }, liveLine(role, live, state.recorder.angles())) : null,
      h("div", { class: "actions" }, buttons));
  }

  function draw() {
    if (!section.isConnected && state.drawn) return;
    state.drawn = true;
    const attached = state.recorder ? SEGMENTS.map((s) => state.recorder.sensors[s]).filter(Boolean) : [];
    clear(sensorsList).append(...(attached.length === 2
      ? SEGMENTS.map((s) => sensorCard(state.recorder.sensors[s], s, fail))
      : state.sensors.map((s) => sensorCard(s, null, fail))));
    connectButton.disabled = state.sensors.length >= 2;
    const connected = state.sensors.length === 2 && state.sensors.every((s) => s.state === "connected");
    clear(identifyArea).append(...(attached.length < 2 ? [identifyButton] : []),
      ...(attached.length === 2 && !state.active ? [swapButton] : []));
    identifyButton.hidden = !connected;
    identifyButton.disabled = !state.recorder || identifying;
    clear(stepsList).append(...STEPS.map(stepItem));
    clear(done).append(STEPS.every((r) => state.status[r] === "stored")
      ? h("a", { href: `#/sessions/${sessionId}/wizard`, class: "button-link primary" }, t("record.to_wizard")) : "");
  }

  // leaving the page lets go of the sensors; a step being recorded stays in the buffer, offered on the next visit
  const leave = (e) => {
    if (state.active || Object.values(state.status).includes("unsent")) {
      e.preventDefault();
      e.returnValue = "";
    }
  };
  window.addEventListener("beforeunload", leave);
  const refresh = setInterval(() => {
    if (!section.isConnected) {
      clearInterval(refresh);
      window.removeEventListener("beforeunload", leave);
      for (const sensor of state.sensors) sensor.disconnect();
      return;
    }
    if (state.active) {
      const item = stepsList.querySelector(`[data-role="${state.active}"] ul.live`);
      if (item) append(clear(item), liveLine(state.active, state.recorder.live(), state.recorder.angles()));
    }
  }, REFRESH_MS);
  // the angle preview's text, every animation frame in which it changed: it shows the newest samples one frame
  // after they arrive instead of waiting up to REFRESH_MS (benchmarks/preview_lag.py measures it)
  const previewFrame = () => {
    if (!section.isConnected) return;
    if (state.active === "task") {
      const angles = state.recorder.angles();
      ANGLES.forEach((name, i) => {
        const span = stepsList.querySelector(`[data-role="task"] ul.live li.preview [data-angle="${name}"]`);
        const text = angleText(name, angles?.[i] ?? null);
        if (span && span.textContent !== text) span.textContent = text;
      });
    }
    requestAnimationFrame(previewFrame);
  };
  requestAnimationFrame(previewFrame);

  section.append(
    h("div", { class: "card" }, h("h2", {}, t("record.sensors_title")), sensorsList,
      h("div", { class: "actions" }, connectButton), identifyArea),
    h("div", {}, h("h2", {}, t("record.steps_title")), stepsList), done);

  // the recorder needs the live checks' thresholds, the server's (app/choices.py live_checks: the pipeline's own);
  // without them nothing can be recorded or uploaded: said, with a button that asks the server again
  async function makeRecorder(again = false) {
    try {
      const served = await options(again);
      state.recorder = new Recorder(sessionId, state.store,
        (segment, role, files) => send(sessionId, segment, role, files), served.live_checks, state.side);
      clear(optionsMessage);
    } catch (err) {
      const retry = h("button", { type: "button", class: "secondary options-retry" }, t("record.options_retry"));
      retry.addEventListener("click", () => { retry.disabled = true; makeRecorder(true); });
      const key = err && err.code === "live_checks_missing" ? "record.error.live_checks_missing" : "record.error.options";
      clear(optionsMessage).append(alertBox(t(key)), retry);
    }
    draw();
  }

  PacketStore.open().then(async (store) => {
    state.store = store;
    // steps buffered by an earlier visit and never acknowledged: offered again (their sensors must be identified),
    // listed whether or not the options can be read
    const [buffered, session] = await Promise.all([store.steps(sessionId), api("GET", `/sessions/${sessionId}`)]);
    // the knee recorded (the angle preview's signs: the left leg mirrored): the session's paired knee, else the patient's
    state.side = session.knee || (await api("GET", `/patients/${session.patient_id}`)).side;
    for (const role of buffered) state.status[role] = "unsent";
    for (const role of STEPS) {
      const stored = (session.recordings || []).filter((r) => r.role === role && SEGMENTS.includes(r.segment));
      if (state.status[role] === "todo" && stored.length >= 2 * 3) state.status[role] = "stored";
    }
    draw();
    await makeRecorder();
  }).catch(fail);
  draw();
  return section;
}
