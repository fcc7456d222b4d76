// The live checks of the protocol's steps while they are recorded (a guide for the clinician; the server's
// ingestion and processing judge the files afterwards).  Inputs are decoded samples in the board's units
// (g, °/s, µT, ./protocol.js).  Every threshold comes from the server (GET /options "live_checks",
// app/choices.py live_checks: the pipeline's own where it has one); the page passes them in, none is typed here.
//
// Figure-eight — sphere coverage: the share of the 20 equal cells of the sphere (centres: the dodecahedron's
//   vertices, as estimators/magnetometer.py) holding ≥ min_cell_samples magnetometer directions (the
//   pipeline's); complete at the pipeline's complete_fraction (below it the pipeline warns MAG_COVERAGE_LOW).
//   The pipeline counts calibrated directions; live, only the hard iron is removed, estimated as the centre of
//   the box the samples span so far (the min/max midpoint of each axis, a running estimate; the sphere is traced
//   by the figure-eight itself), so the live count only predicts the pipeline's.  Directions are binned again
//   whenever that centre moves.  A sample closer than min_field_ut (live only) to that centre has no direction
//   worth counting.
// Postures — stillness: the last window_s (the pipeline's still window, 5 s) is still when the total SD of the
//   gyroscope (√ of the summed per-axis variances, ddof 1, as estimators.knee.stillest_window) is ≤
//   max_gyr_sd_rad_s and that of the accelerometer ≤ max_acc_sd_m_s2: the pipeline's condition itself, so a
//   posture shown still has the window its calibration needs.
// Task — cycles: a step-up turns the segment one way (up onto the step) and back (down again), about one
//   axis: the sensor axis with the most gyroscope power so far.  The rate about it, averaged over average_s,
//   rising above rise_rad_s in the direction of the first such burst after having fallen below fall_rad_s
//   counts one cycle (hysteresis: a burst's wobble never counts twice; the way back, of the other sign, never
//   counts); an approximation shown as such (the server finds the cycles on the knee angles): live-only values.

const PHI = (1 + Math.sqrt(5)) / 2;
const CELLS = (() => {
  const v = [];
  for (const x of [-1, 1]) for (const y of [-1, 1]) for (const z of [-1, 1]) v.push([x, y, z]);
  for (const a of [-1 / PHI, 1 / PHI]) for (const c of [-PHI, PHI]) v.push([0, a, c], [a, c, 0], [c, 0, a]);
  return v.map((p) => p.map((x) => x / Math.sqrt(3)));
})();
/** The number of direction cells (the pipeline's 20). */
export const CELL_COUNT = CELLS.length;
const G_M_S2 = 9.80665;
const DEG = Math.PI / 180;

/** Sphere coverage of magnetometer directions (figure-eight); limits: the served
 * {min_cell_samples, complete_fraction, min_field_ut}. */
export class SphereCoverage {
  constructor(limits) {
    this.minCellSamples = limits.min_cell_samples;
    this.completeFraction = limits.complete_fraction;
    this.minFieldUt = limits.min_field_ut;
    this.samples = [];
    this.lo = [Infinity, Infinity, Infinity];
    this.hi = [-Infinity, -Infinity, -Infinity];
  }

  push(magUt) {
    this.samples.push(magUt);
    for (let i = 0; i < 3; i++) {
      this.lo[i] = Math.min(this.lo[i], magUt[i]);
      this.hi[i] = Math.max(this.hi[i], magUt[i]);
    }
  }

  /** {cells reached, fraction of the 20, need: the cells the pipeline's complete_fraction needs}. */
  coverage() {
    const centre = this.lo.map((l, i) => (l + this.hi[i]) / 2);
    const counts = new Array(CELLS.length).fill(0);
    for (const m of this.samples) {
      const d = m.map((x, i) => x - centre[i]);
      const norm = Math.hypot(...d);
      if (!(norm >= this.minFieldUt)) continue;
      let best = 0;
      let bestDot = -Infinity;
      CELLS.forEach((c, k) => {
        const dot = (c[0] * d[0] + c[1] * d[1] + c[2] * d[2]) / norm;
        if (dot > bestDot) { bestDot = dot; best = k; }
      });
      counts[best] += 1;
    }
    const cells = counts.filter((n) => n >= this.minCellSamples).length;
    const fraction = cells / CELLS.length;
    return { cells, fraction, need: Math.ceil(this.completeFraction * CELLS.length - 1e-9) };
  }
}

/** The last n samples of a stream and their total SD (ddof 1): √(Σ_axes Σ_k (v_k − v̄)² / (n − 1)), in O(1) per
 * sample: a ring of the samples and running sums of d = v − r and d² about a reference r, so that
 * Σ_k (v_k − v̄)² = Σ d² − (Σ d)² / m (m samples).  r is a sample of the window, near its mean, which keeps the
 * subtraction from cancelling (gravity's 9.8 m/s² under an SD of 0.3); the sums are summed afresh from the ring
 * every n samples (and r moved to the newest sample), so rounding never accumulates: O(n) once per n samples. */
class Window {
  constructor(n) {
    this.n = n;
    this.ring = new Array(n);
    this.next = 0;            // where the next sample goes (the oldest one once full)
    this.m = 0;
    this.ref = null;
    this.s1 = [0, 0, 0];
    this.s2 = [0, 0, 0];
    this.sinceSummed = 0;
  }

  push(v) {
    if (this.ref === null) this.ref = v.slice();
    if (this.m === this.n) this.add(this.ring[this.next], -1);
    else this.m += 1;
    this.ring[this.next] = v;
    this.next = (this.next + 1) % this.n;
    this.add(v, 1);
    this.sinceSummed += 1;
    if (this.sinceSummed >= this.n) this.sumAfresh(v);
  }

  add(v, sign) {
    for (let i = 0; i < 3; i++) {
      const d = v[i] - this.ref[i];
      this.s1[i] += sign * d;
      this.s2[i] += sign * d * d;
    }
  }

  sumAfresh(ref) {
    this.ref = ref.slice();
    this.s1 = [0, 0, 0];
    this.s2 = [0, 0, 0];
    for (let k = 0; k < this.m; k++) this.add(this.ring[k], 1);
    this.sinceSummed = 0;
  }

  full() { return this.m >= this.n; }

  totalSd() {
    let sum = 0;
    for (let i = 0; i < 3; i++) sum += Math.max(this.s2[i] - this.s1[i] * this.s1[i] / this.m, 0);
    return Math.sqrt(sum / (this.m - 1));
  }
}

/** Stillness of the last window (postures): push acc (g) and gyro (°/s) samples of one sensor at fsHz;
 * limits: the served {window_s, max_gyr_sd_rad_s, max_acc_sd_m_s2} (the pipeline's). */
export class Stillness {
  constructor(fsHz, limits) {
    this.fsHz = fsHz;
    this.windowS = limits.window_s;
    this.maxGyr = limits.max_gyr_sd_rad_s;
    this.maxAcc = limits.max_acc_sd_m_s2;
    this.n = Math.max(2, Math.round(fsHz * limits.window_s));
    this.acc = new Window(this.n);
    this.gyr = new Window(this.n);
    this.pushed = 0;            // gyroscope samples pushed
    this.coveredTo = 0;         // the end of the last still window, in gyroscope samples
    this.stillSamples = 0;      // samples inside still windows (their union)
    this.isStill = false;
  }

  pushAcc(g) {
    this.acc.push(g.map((x) => x * G_M_S2));
  }

  pushGyr(dps) {
    this.gyr.push(dps.map((x) => x * DEG));
    this.pushed += 1;
    this.isStill = this.acc.full() && this.gyr.full()
      && this.gyr.totalSd() <= this.maxGyr && this.acc.totalSd() <= this.maxAcc;
    if (this.isStill) {
      this.stillSamples += Math.min(this.n, this.pushed - this.coveredTo);
      this.coveredTo = this.pushed;
    }
  }

  /** Whether the last window is still (false until a whole window has arrived). */
  still() {
    return this.isStill;
  }

  /** Seconds of the step inside still windows (0 until one whole window was still). */
  stillSeconds() {
    return this.stillSamples / this.fsHz;
  }
}

/** Cycle count of the task from one sensor's gyroscope (°/s samples at fsHz); limits: the served
 * {average_s, rise_rad_s, fall_rad_s}. */
export class CycleCounter {
  constructor(fsHz, limits) {
    this.window = [];
    this.n = Math.max(1, Math.round(fsHz * limits.average_s));
    this.power = [0, 0, 0];
    this.rise = limits.rise_rad_s / DEG;     // compared with the board's °/s
    this.fall = limits.fall_rad_s / DEG;
    this.sign = 0;          // the counted burst's sign, set by the first burst
    this.armed = true;
    this.cycles = 0;
  }

  push(dps) {
    dps.forEach((x, i) => { this.power[i] += x * x; });
    this.window.push(dps);
    if (this.window.length > this.n) this.window.shift();
    const axis = this.power.indexOf(Math.max(...this.power));
    const mean = this.window.reduce((s, v) => s + v[axis], 0) / this.window.length;
    if (this.armed && Math.abs(mean) > this.rise && (this.sign === 0 || Math.sign(mean) === this.sign)) {
      this.sign = Math.sign(mean);
      this.cycles += 1;
      this.armed = false;
    } else if (!this.armed && Math.abs(mean) < this.fall) {
      this.armed = true;
    }
    return this.cycles;
  }
}
