// Time stamps of streamed MetaWear samples on the browser's clock, and the samples lost on the way.
//
// A streaming MetaWear sends no time and no counter (./protocol.js): the browser knows only when each
// notification arrived.  Sample i of a run (an uninterrupted stretch of streaming) is taken by the sensor at
//     τ_i = τ_0 + i / f_s                                                        (T1, the sensor's clock)
// and, with f_s off by the sensor's clock drift δ (tens of ppm, up to ~1 % in cheap crystals) and a latency
// L_k ≥ 0 of the air and the operating system, the notification k that carries samples up to i_k arrives at
//     a_k = c + b · i_k + L_k,   b = 1 / (f_s (1 + δ))                          (T2, on the browser's clock)
// The least-squares line of a_k over i_k (Legendre), each a_k first lowered to the earliest arrival the next few
// notifications imply (a lower envelope: latency is never negative, its bursts only delay), gives the stamp
// of every sample, t_i = c + b · i (T3), and the drift δ = 1/(b f_s) − 1.  Both
// sensors are stamped on the same browser clock, so T3 aligns them: their own clocks (and their drifts) drop
// out, as the phone's clock does for MetaBase's CSV files, whose epoch column is the phone's time.
//
// Lost notifications: a lost notification makes every later one of its run look one packet period P = b·(samples
// per notification) late for good, while a latency burst holds back only a few.  So, with the notifications
// of a run numbered k = 0, 1, … as if none were lost, the lateness e_k = a_k − a_0 − P·k is taken as its
// running minimum over the next W = 16 notifications (longer than a burst), s_k = min(e_k … e_{k+W−1}), and
//     m_k = m_{k−1} + max(0, round((s_k − s_{k−1}) / P)),   m_0 = 0                          (T4)
// notifications were lost before notification k; its first sample is (k + m_k)·(samples per notification).  P
// starts at the nominal period and is taken once more from the line (T3) through the placed notifications
// (a drift of 1 % moves a 30 s run by 300 ms, ten packet periods).  A whole gap (seconds without data) is the
// same jump, counted the same way.  A jump needs W notifications after it to be told from a burst, so a loss
// among a run's last W − 1 notifications (0.45 s of packed 100 Hz data) is not placed: those few samples are
// stamped up to that many packet periods early.  A disconnection ends the run; the next run starts its own line after the
// reconnection (the gap between runs stays a gap: the ingestion reads it as missing rows).
// The placement is computed from all arrivals of the run whenever asked (at a step's end for the files, now
// and then for the live loss count): O(W) per notification.

/** Fit a_k = c + b·i_k by least squares (T2); null with fewer than two points or no spread in i. */
export function fitLine(indices, arrivalsMs) {
  const n = indices.length;
  if (n < 2) return null;
  let mi = 0;
  let ma = 0;
  for (let k = 0; k < n; k++) { mi += indices[k]; ma += arrivalsMs[k]; }
  mi /= n;
  ma /= n;
  let sii = 0;
  let sia = 0;
  for (let k = 0; k < n; k++) {
    const di = indices[k] - mi;
    sii += di * di;
    sia += di * (arrivalsMs[k] - ma);
  }
  if (sii === 0) return null;
  const b = sia / sii;
  return { c: ma - b * mi, b };
}

const WINDOW = 16;   // W of (T4): notifications over which the lateness' minimum is taken

/** The line (T3) through the earliest arrivals: each arrival replaced by the running minimum over the next W
 * notifications of its lateness against a line of slope `msPerSample`, then the least-squares line of those.
 * The minima carry the smallest latency of each window instead of every burst, so the drift they give is
 * steadier than that of the raw arrivals, and the stamps sit nearer the sampling instants. */
function envelopeLine(indices, arrivalsMs, msPerSample) {
  const late = arrivalsMs.map((a, k) => a - msPerSample * indices[k]);
  // only full windows: a short one at the run's end would lift its minima and tilt the line
  const full = indices.length >= 2 * WINDOW ? indices.length - WINDOW + 1 : indices.length;
  const floor = late.slice(0, full).map((_, k) => Math.min(...late.slice(k, k + WINDOW)) + msPerSample * indices[k]);
  return fitLine(indices.slice(0, full), floor);
}

/** The first-sample index of each notification of one run (T4) and the run's line (T3).
 * arrivalsMs: arrival times in order; per: samples per notification; nominalMs: the nominal packet period. */
export function placeRun(arrivalsMs, per, nominalMs) {
  const n = arrivalsMs.length;
  let periodMs = nominalMs;
  let first = [];
  let line = null;
  for (let pass = 0; pass < 2; pass++) {
    const late = arrivalsMs.map((a, k) => a - arrivalsMs[0] - periodMs * k);
    const floor = late.map((_, k) => Math.min(...late.slice(k, k + WINDOW)));
    let lostBefore = 0;
    first = floor.map((s, k) => {
      if (k > 0 && k + WINDOW <= n) lostBefore += Math.max(0, Math.round((s - floor[k - 1]) / periodMs));
      return (k + lostBefore) * per;
    });
    line = envelopeLine(first.map((i) => i + per - 1), arrivalsMs, periodMs / per);
    if (!line) break;
    periodMs = line.b * per;
  }
  line ??= { c: (arrivalsMs[0] ?? 0) - (nominalMs / per) * (per - 1), b: nominalMs / per };
  const lost = n ? first[n - 1] / per + 1 - n : 0;
  return { first, line, lost: lost * per };
}

/** One stream of one sensor: notification arrivals in, sample stamps and losses out. */
export class StreamTimeline {
  /** fsHz: the configured rate; perPacket: samples per notification (3 packed, 1 single). */
  constructor(fsHz, perPacket = 1) {
    this.fsHz = fsHz;
    this.perPacket = perPacket;
    this.runs = [];
    this.newRun();
  }

  /** Start a new run (after a reconnection): its samples count from 0 again on a line of their own. */
  newRun() {
    const last = this.runs[this.runs.length - 1];
    if (!last || last.length > 0) this.runs.push([]);
  }

  /** A notification arrived at `arrivalMs` (epoch ms, may be fractional); returns [run, its number in the run]. */
  push(arrivalMs) {
    const run = this.runs[this.runs.length - 1];
    run.push(arrivalMs);
    return [this.runs.length - 1, run.length - 1];
  }

  /** Every run placed (T3, T4): [{first: [index of each notification's first sample], line: {c, b}, lost}]. */
  placement() {
    return this.runs.map((run) => placeRun(run, this.perPacket, (1000 / this.fsHz) * this.perPacket));
  }

  /** Samples judged lost inside the runs (not those of a disconnection's gap between runs). */
  lost(placed = this.placement()) {
    return placed.reduce((sum, p) => sum + p.lost, 0);
  }

  /** The sensor's clock drift from the longest run, ppm (δ of T2), or null before a fit. */
  driftPpm(placed = this.placement()) {
    const run = placed.reduce((a, p) => (p.first.length > (a?.first.length ?? -1) ? p : a), null);
    return run && run.first.length >= 2 ? (1000 / (run.line.b * this.fsHz) - 1) * 1e6 : null;
  }
}

/** Integer epoch ms of sample `index` on a run's line (T3), as MetaBase writes its epoch column. */
export function stampMs(line, index) {
  return Math.round(line.c + line.b * index);
}
