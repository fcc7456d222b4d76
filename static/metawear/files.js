// A recorded step's buffered notifications (./store.js records) → the MetaBase CSV files of each sensor, with
// their SHA-256 (the upload route answers the sha256 of every stored file: a match is the acknowledgement).
//
// Per segment and stream: the notifications are decoded again (./protocol.js), placed on their runs by
// ./timeline.js (stamps on the browser's clock, losses), and written by ./csv.js.  Samples stamped on or
// before the previous one (a reconnection's new run starting within a few ms of the old one's last stamp)
// are dropped, as the format needs strictly increasing stamps; none is dropped otherwise.

import * as protocol from "./protocol.js";
import { StreamTimeline, stampMs } from "./timeline.js";
import { csvText, fileName, utcOffsetMin } from "./csv.js";

/** {segment: {stream: {epochMs: [...], values: [[x, y, z], ...], lost, driftPpm}}} of a step's records;
 * chips: {segment: the chips of the sensor that recorded it} (their data registers differ, ./protocol.js). */
export function streamsOf(records, config = protocol.PROTOCOL_CONFIG, chips = {}) {
  const scale = protocol.sensitivities(config);
  const rates = { acc: config.accHz, gyr: config.gyrHz, mag: config.magHz };
  const groups = new Map();
  for (const r of records) {
    const key = `${r.segment}/${r.stream}`;
    if (!groups.has(key)) groups.set(key, []);
    groups.get(key).push(r);
  }
  const out = {};
  for (const [key, recs] of groups) {
    const [segment, stream] = key.split("/");
    const board = chips[segment] ?? protocol.BMI160_BOARD;
    const per = stream !== "mag" && board.packed?.[stream] ? 3 : 1;      // samples per notification
    const timeline = new StreamTimeline(rates[stream], per);
    let run = recs[0].run;
    const decoded = recs.map((r) => {
      if (r.run !== run) { timeline.newRun(); run = r.run; }
      const [runIndex, k] = timeline.push(r.arrivalMs);
      return { runIndex, k, values: protocol.decode(new Uint8Array(r.bytes), scale, board).values };
    });
    const placed = timeline.placement();
    const epochMs = [];
    const values = [];
    for (const d of decoded) {
      const { first, line } = placed[d.runIndex];
      d.values.forEach((v, j) => {
        const ms = stampMs(line, first[d.k] + j);
        if (epochMs.length && ms <= epochMs[epochMs.length - 1]) return;
        epochMs.push(ms);
        values.push(v);
      });
    }
    out[segment] ??= {};
    out[segment][stream] = { epochMs, values, lost: timeline.lost(placed), driftPpm: timeline.driftPpm(placed),
      rateHz: rates[stream] };
  }
  return out;
}

async function sha256Hex(text) {
  const digest = await crypto.subtle.digest("SHA-256", new TextEncoder().encode(text));
  return Array.from(new Uint8Array(digest), (b) => b.toString(16).padStart(2, "0")).join("");
}

/** The three files of one sensor's step, named as MetaBase names a recording's files (label, serial and the
 * recording's first stamp, in the browser's local time, shared): [{name, text, sha256}]; label names role and segment
 * (e.g. "task-thigh"), sensor = {serial, firmware}. */
export async function filesOf(streams, label, sensor) {
  const files = [];
  const kinds = ["acc", "gyr", "mag"].filter((k) => streams[k] && streams[k].epochMs.length > 0);
  // the three names share the recording's first stamp: the ingestion groups a recording's files by it
  const startMs = Math.min(...kinds.map((k) => streams[k].epochMs[0]));
  // local time, as MetaBase writes it: the browser's UTC offset at the recording's start, for all three files
  const offsetMin = utcOffsetMin(startMs);
  for (const stream of kinds) {
    const s = streams[stream];
    const text = csvText(stream, s.epochMs, s.values, offsetMin);
    const name = fileName(label, startMs, sensor.serial, stream, s.rateHz, sensor.firmware || "unknown", offsetMin);
    files.push({ name, text, sha256: await sha256Hex(text) });
  }
  return files;
}
