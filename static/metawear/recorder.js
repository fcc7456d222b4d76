// The recording of one session's protocol from two sensors, without the page: which sensor is on which
// segment, the step being recorded, its buffered notifications and live checks, and the upload of each step.
//
// Steps: the protocol's four recordings (roles mag_calibration, standing, lying, task), each recorded from
// both sensors at once.  Each notification of a step goes into the IndexedDB buffer (./store.js) with its
// segment, stream, run (a sensor's run changes when it reconnects) and arrival time; the store is flushed
// every FLUSH_MS.  At a step's end its files are made from the buffer (./files.js) and uploaded per segment
// as the upload route takes them (segment and role fields, POST /sessions/{id}/recordings); the answer's
// sha256 of every file must equal the browser's own before the step's buffer is cleared: that is the
// acknowledgement.  Anything else leaves the buffer as it is, to upload again (also after a reload: the serial
// and firmware of the step's sensors, which its file names carry, are kept in localStorage at its start).
//
// Identification (which sensor is on the thigh): both sensors stream while the clinician moves the thigh; the
// first sensor whose gyroscope norm, averaged over 0.3 s, passes 60 °/s while the other's stays under 20 °/s
// is the thigh's (none within 30 s: the streams stop and the clinician is asked to try again).

import { SphereCoverage, Stillness, CycleCounter } from "./checks.js";
import { MeanForce, KneePreview, segmentAxes } from "./preview.js";
import { streamsOf, filesOf } from "./files.js";
import { PROTOCOL_CONFIG } from "./protocol.js";

export const STEPS = Object.freeze(["mag_calibration", "standing", "lying", "task"]);
export const SEGMENTS = Object.freeze(["thigh", "shank"]);
const LABEL = Object.freeze({ mag_calibration: "calibration", standing: "standing", lying: "lying", task: "task" });
const FLUSH_MS = 250;
const COMPLETE = 0.8;        // the share of span × rate samples each stream of a step must hold
const MOVE_DPS = 60;
const QUIET_DPS = 20;
const IDENTIFY_MS = 30000;   // no sensor moved alone by then: the clinician is asked to try again

/** The label a step's file names start with for one segment (e.g. "task-thigh"): the files this recorder made. */
export function fileLabel(role, segment) {
  return `${LABEL[role]}-${segment}`;
}

// the serial and firmware of the sensors that recorded a step, for its file names (kept beside its buffer)
function sensorsKey(sessionId, role) {
  return `chakamo.record.${sessionId}.${role}`;
}

function saveSensors(sessionId, role, sensors) {
  try { localStorage.setItem(sensorsKey(sessionId, role), JSON.stringify(sensors)); } catch (_) { /* storage off */ }
}

function loadSensors(sessionId, role) {
  try { return JSON.parse(localStorage.getItem(sensorsKey(sessionId, role))); } catch (_) { return null; }
}

class MotionMeter {
  constructor(n = 30) { this.n = n; this.window = []; }
  push(dps) {
    this.window.push(Math.hypot(...dps));
    if (this.window.length > this.n) this.window.shift();
    return this.window.reduce((a, b) => a + b, 0) / this.window.length;
  }
}

/** Refuse a step whose streams are not all there: each of both sensors' three streams must hold at least
 * COMPLETE of span × rate samples, span being the step's time from its first to its last notification (any
 * sensor).  A sensor lost for good, a stream that never started: the step is not uploaded (code "incomplete").
 * A reconnection's gap of a few seconds in a task stays well above it. */
function incomplete(records, streams, config = PROTOCOL_CONFIG) {
  const rates = { acc: config.accHz, gyr: config.gyrHz, mag: config.magHz };
  let t0 = Infinity;
  let t1 = -Infinity;
  for (const r of records) { t0 = Math.min(t0, r.arrivalMs); t1 = Math.max(t1, r.arrivalMs); }
  const spanS = (t1 - t0) / 1000;
  for (const segment of SEGMENTS) {
    for (const stream of ["acc", "gyr", "mag"]) {
      const n = streams[segment]?.[stream]?.epochMs.length ?? 0;
      const expected = spanS * rates[stream];
      if (n === 0 || n < COMPLETE * expected) {
        throw Object.assign(new Error(`${segment} ${stream}: ${n} of ~${Math.round(expected)} samples`),
          { code: "incomplete" });
      }
    }
  }
}

export class Recorder {
  /** sessionId; store: a PacketStore; send(segment, role, files) → the upload route's answer; liveChecks: the
   * thresholds of the live checks as the server serves them (GET /options "live_checks", ./checks.js); side: the
   * knee recorded, "right" or "left" (the angle preview's signs, ./preview.js). */
  constructor(sessionId, store, send, liveChecks, side = "right") {
    if (!liveChecks?.stillness || !liveChecks.coverage || !liveChecks.cycles) {
      throw Object.assign(new Error("the live checks' thresholds (GET /options live_checks) are missing"),
        { code: "live_checks_missing" });
    }
    this.limits = liveChecks;
    this.sessionId = sessionId;
    this.store = store;
    this.send = send;
    this.sensors = {};          // segment → MetaWearSensor (after identification)
    this.runs = {};             // segment → current run number
    this.step = null;
    this.checks = null;
    this.counts = null;
    this.listeners = new Set();
    this.flushTimer = null;
    this.side = side;
    // segment → role → {acc, gyr}: MeanForce of each stream (the preview's segment axes and gyroscope bias)
    this.postures = Object.fromEntries(SEGMENTS.map((s) => [s, {}]));
    this.preview = null;
  }

  changed() {
    for (const fn of this.listeners) fn();
  }

  /** Route one sensor's samples here (its segment known). */
  attach(segment, sensor) {
    this.sensors[segment] = sensor;
    this.runs[segment] = this.runs[segment] ?? 0;
    sensor.handlers.onSamples = (kind, values, arrivalMs, raw) => this.samples(segment, kind, values, arrivalMs, raw);
    // a new run from the drop on: nothing of the reconnection is stamped on the old run's line
    // and the angle preview takes that sensor's attitude from scratch (the gap's motion is unknown)
    sensor.handlers.onDropped = () => { this.runs[segment] += 1; this.preview?.restart(segment); this.changed(); };
    sensor.handlers.onReconnect = () => this.changed();
    // a notification the board's table cannot decode (its chip misread, a corrupted packet): counted, shown
    sensor.handlers.onBadPacket = () => { if (this.step) this.bad[segment] += 1; };
  }

  /** Stream both sensors until one is moved alone: resolves to [thigh sensor, shank sensor]. */
  identify(a, b) {
    return new Promise((resolve, reject) => {
      const meters = [new MotionMeter(), new MotionMeter()];
      const level = [0, 0];
      const done = async (thigh) => {
        a.handlers.onSamples = null;
        b.handlers.onSamples = null;
        try {
          await Promise.all([a.stop(), b.stop()]);
          resolve(thigh === 0 ? [a, b] : [b, a]);
        } catch (err) { reject(err); }
      };
      let decided = false;
      const timer = setTimeout(async () => {
        if (decided) return;
        decided = true;
        a.handlers.onSamples = null;
        b.handlers.onSamples = null;
        await Promise.allSettled([a.stop(), b.stop()]);
        reject(Object.assign(new Error("no sensor moved alone"), { code: "not_identified" }));
      }, IDENTIFY_MS);
      [a, b].forEach((sensor, i) => {
        sensor.handlers.onSamples = (kind, values) => {
          if (kind !== "gyr" || decided) return;
          for (const v of values) level[i] = meters[i].push(v);
          if (level[i] > MOVE_DPS && level[1 - i] < QUIET_DPS) {
            decided = true;
            clearTimeout(timer);
            done(i);
          }
        };
      });
      Promise.all([a.start(), b.start()]).catch(reject);
    });
  }

  /** Start recording `role` on both sensors.  Its earlier buffer, if any, is dropped: the caller asks the
   * clinician first (an unsent take is the only copy of its samples). */
  async start(role) {
    await this.store.clear(this.sessionId, role);
    saveSensors(this.sessionId, role, Object.fromEntries(SEGMENTS.map((s) => [s, {
      serial: this.sensors[s].info.serial, firmware: this.sensors[s].info.firmware, chips: this.sensors[s].info.chips }])));
    this.step = role;
    this.counts = Object.fromEntries(SEGMENTS.map((s) => [s, { acc: 0, gyr: 0, mag: 0 }]));
    this.bad = Object.fromEntries(SEGMENTS.map((s) => [s, 0]));
    // each step runs the one check it shows: coverage on the figure-eight, stillness on the postures, cycles on the task
    const fs = PROTOCOL_CONFIG.gyrHz;
    const posture = role === "standing" || role === "lying";
    this.checks = Object.fromEntries(SEGMENTS.map((s) => [s, {
      coverage: role === "mag_calibration" ? new SphereCoverage(this.limits.coverage) : null,
      stillness: posture ? new Stillness(fs, this.limits.stillness) : null,
      cycles: role === "task" ? new CycleCounter(fs, this.limits.cycles) : null }]));
    if (posture) for (const s of SEGMENTS) this.postures[s][role] = { acc: new MeanForce(), gyr: new MeanForce() };
    this.preview = role === "task" ? this.kneePreview(fs) : null;
    // a failed write keeps its records queued and is retried at the next tick; meanwhile it is shown (live)
    this.bufferError = null;
    this.flushTimer = setInterval(() => this.store.flush().then(() => { this.bufferError = null; },
      (err) => { this.bufferError = err; this.changed(); }), FLUSH_MS);
    try {
      await Promise.all(SEGMENTS.map((s) => this.sensors[s].start()));
    } catch (err) {
      // one sensor did not start: none records, the step stays as it was (its buffer is empty)
      await Promise.allSettled(SEGMENTS.map((s) => this.sensors[s].stop()));
      clearInterval(this.flushTimer);
      this.step = null;
      await this.store.clear(this.sessionId, role);
      throw err;
    }
    this.changed();
  }

  samples(segment, kind, values, arrivalMs, raw) {
    if (!this.step) return;
    this.store.add({ session: this.sessionId, step: this.step, segment, stream: kind, run: this.runs[segment],
      arrivalMs, bytes: raw.buffer });
    this.counts[segment][kind] += values.length;
    const c = this.checks[segment];
    const posture = this.postures[segment][this.step];
    const preview = this.preview;
    for (const v of values) {
      if (kind === "mag") c.coverage?.push(v);
      else if (kind === "acc") {
        c.stillness?.pushAcc(v);
        posture?.acc.push(v);
        preview?.pushAcc(segment, v);
      } else {
        c.stillness?.pushGyr(v);
        c.cycles?.push(v);
        posture?.gyr.push(v);
        preview?.pushGyr(segment, v);
      }
    }
  }

  /** The knee angle preview of a task (./preview.js) from the standing and supine steps recorded in this visit:
   * their mean specific force (the segment axes) and mean gyroscope (its bias, both postures still); null
   * without them. */
  kneePreview(fsHz) {
    const axes = {};
    const bias = {};
    for (const s of SEGMENTS) {
      const { standing, lying } = this.postures[s];
      if (!standing?.acc.n || !lying?.acc.n) return null;
      axes[s] = segmentAxes(standing.acc.mean(), lying.acc.mean());
      const n = standing.gyr.n + lying.gyr.n;
      bias[s] = n ? standing.gyr.sum.map((v, i) => (v + lying.gyr.sum[i]) / n) : [0, 0, 0];
    }
    return new KneePreview(axes, bias, this.side, fsHz);
  }

  /** The knee angles' preview, degrees, [flexion, adduction, internal rotation] (./preview.js), during a task
   * once standing and supine were recorded in this visit; null otherwise. */
  angles() {
    return this.preview?.angles() ?? null;
  }

  /** The live figures of the step being recorded, per segment. */
  live() {
    if (!this.checks) return null;
    const live = Object.fromEntries(SEGMENTS.map((s) => {
      const c = this.checks[s];
      // the step's own check; the others null
      return [s, { samples: this.counts[s], bad: this.bad[s], coverage: c.coverage?.coverage() ?? null,
        still: c.stillness?.still() ?? null, stillS: c.stillness?.stillSeconds() ?? null,
        stillNeedS: c.stillness?.windowS ?? null, cycles: c.cycles?.cycles ?? null,
        state: this.sensors[s]?.state, battery: this.sensors[s]?.info.battery }];
    }));
    return { ...live, bufferError: this.bufferError ? String(this.bufferError.message || this.bufferError) : null };
  }

  /** Stop the step and upload it; resolves to {role, lost: {segment: samples}, recordings} once acknowledged. */
  async stop() {
    const role = this.step;
    // a sensor that cannot be told to stop (out of reach) does not keep the step from being uploaded
    await Promise.allSettled(SEGMENTS.map((s) => this.sensors[s].stop()));
    clearInterval(this.flushTimer);
    this.step = null;
    await this.store.flush();
    this.changed();
    return this.upload(role);
  }

  /** Make a buffered step's files, upload them, and clear the buffer once the server's sha256 match. */
  async upload(role) {
    const records = await this.store.step(this.sessionId, role);
    if (records.length === 0) throw Object.assign(new Error(`no buffered data for ${role}`), { code: "no_data" });
    // the sensors that recorded the step (saved at its start), not those connected now (after a reload)
    const sensors = loadSensors(this.sessionId, role)
      ?? Object.fromEntries(SEGMENTS.map((s) => [s, this.sensors[s]?.info]));
    const streams = streamsOf(records, undefined, Object.fromEntries(SEGMENTS.map((s) => [s, sensors[s]?.chips])));
    incomplete(records, streams);
    const recordings = [];
    const lost = {};
    for (const segment of SEGMENTS) {
      const sensor = sensors[segment];
      const files = await filesOf(streams[segment], fileLabel(role, segment), sensor);
      const answer = await this.send(segment, role, files);
      const stored = new Map(answer.recordings.map((r) => [r.file_name, r]));
      for (const f of files) {
        const r = stored.get(f.name);
        if (!r || r.sha256 !== f.sha256) {
          throw Object.assign(new Error(`the server did not acknowledge ${f.name}`), { code: "not_acknowledged" });
        }
        recordings.push(r);
      }
      lost[segment] = Object.values(streams[segment]).reduce((n, s) => n + s.lost, 0);
    }
    await this.store.clear(this.sessionId, role);
    return { role, lost, recordings };
  }
}
