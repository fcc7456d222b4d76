// The results page's 3D view: viser's static client (/viser/index.html, same origin) playing the analysis'
// scene.viser in an <iframe>, with a jump-to-cycle control like `chakamo view`'s.
//
// First frame: the client boots (served unpacked: app/web/viser_client.py), fetches the recording and draws, on
// the page's own thread (a same-origin frame), after and among the page's plotly charts.  A lazy iframe started all
// of that only once within Chromium's lazy-loading distance of the view; the frame now starts with the page, so the
// boot runs while the clinician reads the numbers above, and a "loading" line stands in the box until the recording
// plays (no blank box).  `python -m benchmarks.scene_first_frame` measures both in Chromium.  (Tried: giving the
// source at the first idle moment after the charts; on a loaded machine the idle callback waited its whole timeout,
// later than eager.)
// Tried: charts held until its first frames (3735802): no gain on a quiet machine, 3164 ms with vs 2894 without; scrolled-to 2344 vs 68 ms.
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

/** The 3D card of analysis `analysisId` of session `sessionId` (`r`: its results.json, for the cycles). */
export function sceneSection(sessionId, analysisId, r) {
  const scene = apiUrl(`/sessions/${sessionId}/scene.viser`, { analysis_id: analysisId });
  const src = `/viser/index.html?playbackPath=${encodeURIComponent(scene)}`;
  // eager (no loading=lazy): the page grew (the cycles and pairing cards), which put the frame beyond Chromium's
  // lazy-loading distance, so its boot would start only when scrolled to
  const frame = h("iframe", { id: "scene-frame", src, title: t("results.scene_title"), allow: "fullscreen" });
  const loading = h("p", { class: "scene-loading", id: "scene-loading", role: "status" }, t("scene.loading"));
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
  const box = h("div", { class: "scene-box" }, frame, loading);
  // "loading" until the recording plays (its playback bar exists); then the jump control works.  The poll stops
  // then, when the page is left, or after READY_TIMEOUT_MS with an error in the box (scene.viser did not load)
  const started = Date.now();
  const ready = setInterval(() => {
    if (!frame.isConnected) { clearInterval(ready); return; }
    if (timeField(frame)) {
      clearInterval(ready);
      loading.remove();
      jump.disabled = false;
      box.dataset.ready = "true";
    } else if (Date.now() - started > READY_TIMEOUT_MS) {
      clearInterval(ready);
      loading.textContent = t("scene.failed");
      loading.classList.add("error");
      box.dataset.ready = "failed";
    }
  }, 100);
  return h("section", { class: "card scene", "aria-labelledby": "h-scene" },
    h("h2", { id: "h-scene" }, t("results.scene")), h("p", { class: "hint" }, t("results.scene_hint")),
    h("div", { class: "toolbar scene-tools" }, h("label", { for: "scene-cycle" }, t("scene.jump")), jump),
    box,
    h("p", {}, h("a", { href: src, target: "_blank", rel: "noopener" }, t("results.scene_open"))));
}
