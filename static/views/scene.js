// The results page's 3D view: viser's static client (/viser/index.html, same origin) playing the analysis'
// scene.viser in an <iframe>, with a jump-to-cycle control like `chakamo view`'s.
//
// First frame (issue 17 §4: within 1 s).  viser's client boots (served unpacked: app/web/viser_client.py), fetches the
// recording and draws on the page's own main thread (a same-origin frame), beside plotly: a Chromium performance
// trace (`python -m benchmarks.scene_first_frame --trace DIR`) showed plotly.min.js' evaluation (1.5-3 s) and the
// client's module evaluation, recording decoding and first WebGL frame (1.2 s and more) one after the other on that
// thread, so viser's own first frame cannot come within 1 s on the clinic's two-core machine with software WebGL.
// The box therefore first shows the recording's first frame as a still picture drawn by ChakaMo from the same
// scene.viser (GET /sessions/{id}/scene.png: the meshes, poses and camera of its first state, reports/scene_still.py;
// flat shading, no label), captioned as such, and only then starts viser's frame and the page's charts (plotly),
// so that nothing holds the main thread before the picture is painted (at most STILL_WAIT_MS).  When the recording
// plays (viser's playback bar exists) the picture gives way to viser's canvas.  The benchmark measures both: the
// still's paint (Element Timing) and viser's first bone draw.
// Tried: charts held until viser's first frames (3735802): no gain on a quiet machine, 3164 ms with vs 2894 without.
//
// Jump to cycle: the recorded scene's time axis is the task's (sample 0 at 0 s: results.json cycles.boundaries_s),
// and viser's playback client has no API to seek from outside; its time field is a plain <input> in the same-origin
// frame, so the control types the cycle's start into it (the client's own handler seeks and pauses there) and
// presses its play button.  Pinned to the viser version of pyproject; the browser test fails if the field moves.

import { apiUrl } from "../api.js";
import { h, num } from "../dom.js";
import { t } from "../i18n.js";

const TIME_FIELD = ".mantine-NumberInput-input";     // viser's playback time field (FilePlayback.tsx)

/** The playback bar's time field of the client in `frame`, once the recording is loaded (else null). */
function timeField(frame) {
  try {
    return frame.contentDocument ? frame.contentDocument.querySelector(TIME_FIELD) : null;
  } catch (_) {
    return null;                                     // not (yet) same-origin: about:blank
  }
}

const PLAYING_CHECK_MS = 600;                        // time for a playing client to move its time field on
const READY_TIMEOUT_MS = 120000;                     // no playback bar by then: the scene did not load
const STILL_WAIT_MS = 1500;                          // the most the iframe and the charts wait for the still

/** Seek the client in `frame` to `seconds` and play from there.  Its one button toggles play and pause, and
 * whether the seek paused it depends on its state, so the state is read, not assumed: if the time field has not
 * moved on shortly after pressing play, the client is paused and the button is pressed once more. */
function seek(frame, seconds) {
  const input = timeField(frame);
  if (!input) return false;
  const setter = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, "value").set;
  input.focus();
  setter.call(input, seconds.toFixed(2));
  input.dispatchEvent(new Event("input", { bubbles: true }));   // the client seeks there
  input.blur();
  const bar = input.closest(".mantine-Paper-root");
  const play = bar ? bar.querySelector("button") : null;        // its first button: play / pause
  if (!play) return true;
  play.click();
  setTimeout(() => {
    const now = timeField(frame);
    if (now && Number(now.value) === Number(seconds.toFixed(2))) play.click();   // still paused: press again
  }, PLAYING_CHECK_MS);
  return true;
}

/** The still first frame's <img> of analysis `analysisId`: made (and so requested) as soon as the page knows the
 *  analysis, while it still fetches the results, then handed to sceneSection. */
export function stillImage(sessionId, analysisId) {
  return h("img", { id: "scene-still", class: "scene-still", alt: t("scene.still_alt"), elementtiming: "scene-still",
    src: apiUrl(`/sessions/${sessionId}/scene.png`, { analysis_id: analysisId }) });
}

/** A promise resolved once `img` is on screen (decoded, then one painted frame), failed to load, or after `ms`. */
function painted(img, ms) {
  const shown = img.decode().then(() => new Promise((resolve) => requestAnimationFrame(() => setTimeout(() => resolve("painted"), 0))));
  return Promise.race([shown.catch(() => "failed"), new Promise((resolve) => setTimeout(() => resolve("late"), ms))]);
}

/** The 3D card of analysis `analysisId` of session `sessionId` (`r`: its results.json, for the cycles);
 *  `preloaded`: its still from stillImage, when the page made it earlier.  Its `firstFrame` promise resolves
 *  ("painted", "failed" or "late") once the still first frame is painted (or could not be): the page's charts wait
 *  for it, so that plotly's evaluation does not hold the picture back. */
export function sceneSection(sessionId, analysisId, r, preloaded = null) {
  const scene = apiUrl(`/sessions/${sessionId}/scene.viser`, { analysis_id: analysisId });
  const src = `/viser/index.html?playbackPath=${encodeURIComponent(scene)}`;
  // eager (no loading=lazy): the page grew (the cycles and pairing cards), which put the frame beyond Chromium's
  // lazy-loading distance, so its boot would start only when scrolled to; its src is set once the still is painted
  const frame = h("iframe", { id: "scene-frame", title: t("results.scene_title"), allow: "fullscreen" });
  const still = preloaded || stillImage(sessionId, analysisId);
  const stillNote = h("p", { class: "scene-still-note", id: "scene-still-note", role: "status" }, t("scene.still_note"));
  const broken = () => { still.remove(); stillNote.textContent = t("scene.loading"); };
  const failedEarly = still.complete && still.naturalWidth === 0;   // it failed before this card was made
  if (failedEarly) broken();
  else still.addEventListener("error", broken);
  const cycles = r.cycles || {};
  const bounds = cycles.boundaries_s || [];
  const accepted = new Set(cycles.accepted_indices || []);
  const jump = h("select", { id: "scene-cycle", name: "cycle", disabled: true },
    h("option", { value: "" }, t("scene.jump_choose")),
    bounds.map((b, i) => (accepted.has(i) && Array.isArray(b) && typeof b[0] === "number"
      ? h("option", { value: String(b[0]) }, t("scene.jump_option", { n: i + 1, start: num(b[0], 1) })) : null)));
  jump.addEventListener("change", () => {
    if (jump.value !== "") seek(frame, Number(jump.value));
  });
  const box = h("div", { class: "scene-box", "data-ready": "still" }, frame, failedEarly ? null : still, stillNote);
  const firstFrame = painted(still, STILL_WAIT_MS);
  // the still (or its caption) until the recording plays (its playback bar exists); then the jump control works.
  // The poll stops then, when the page is left, or after READY_TIMEOUT_MS with an error in the box
  firstFrame.then((how) => {
    box.dataset.still = how;               // "painted", "failed" or "late": what came before viser's frame
    if (!box.isConnected) return;
    frame.src = src;
    const started = Date.now();
    const ready = setInterval(() => {
      if (!box.isConnected) { clearInterval(ready); return; }
      if (timeField(frame)) {
        clearInterval(ready);
        still.remove();
        stillNote.remove();
        jump.disabled = false;
        box.dataset.ready = "true";
      } else if (Date.now() - started > READY_TIMEOUT_MS) {
        clearInterval(ready);
        stillNote.textContent = t("scene.failed");
        stillNote.classList.add("error");
        box.dataset.ready = "failed";
      }
    }, 100);
  });
  const section = h("section", { class: "card scene", "aria-labelledby": "h-scene" },
    h("h2", { id: "h-scene" }, t("results.scene")), h("p", { class: "hint" }, t("results.scene_hint")),
    h("div", { class: "toolbar scene-tools" }, h("label", { for: "scene-cycle" }, t("scene.jump")), jump),
    box,
    h("p", {}, h("a", { href: src, target: "_blank", rel: "noopener" }, t("results.scene_open"))));
  section.firstFrame = firstFrame;
  return section;
}
