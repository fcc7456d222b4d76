// The live checks of the protocol's steps while they are recorded (a guide for the clinician; the server's
// ingestion and processing judge the files afterwards).  Inputs are decoded samples in the board's units
// (g, °/s, µT, ./protocol.js).
//
// Figure-eight — sphere coverage: the share of the 20 equal cells of the sphere (centres: the dodecahedron's
//   vertices, as estimators/magnetometer.py) holding ≥ 3 magnetometer directions.  The pipeline counts
//   calibrated directions; live, only the hard iron is removed, estimated as the centre of the box the
//   samples span so far (the min/max midpoint of each axis, a running estimate; the sphere is traced by
//   the figure-eight itself).  Directions are binned again whenever that centre moves.  A sample closer than
//   MIN_RADIUS_UT = 15 µT to that centre has no direction worth counting (the Earth's field is 25–65 µT; a
//   still sensor's samples all sit within its noise of their own box's centre).
// Postures — stillness: a 0.5 s window is still when the total SD of the gyroscope (√ of the summed per-axis
//   variances) is ≤ 0.05 rad/s and that of the accelerometer ≤ 0.3 m/s²: estimators.knee's
//   STILL_MAX_GYR_SD_RAD_S and STILL_MAX_ACC_SD_M_S2 (a test holds the two equal).
// Task — cycles: a step-up turns the segment one way (up onto the step) and back (down again), about one
//   axis: the sensor axis with the most gyroscope power so far.  The rate about it, averaged over 0.3 s,
//   rising above 60 °/s in the direction of the first such burst after having fallen below 20 °/s counts one
//   cycle (hysteresis: a burst's wobble never counts twice; the way back, of the other sign, never counts);
//   an approximation shown as such (the server finds the cycles on the knee angles).

const PHI = (1 + Math.sqrt(5)) / 2;
const CELLS = (() => {
  const v = [];
  for (const x of [-1, 1]) for (const y of [-1, 1]) for (const z of [-1, 1]) v.push([x, y, z]);
  for (const a of [-1 / PHI, 1 / PHI]) for (const c of [-PHI, PHI]) v.push([0, a, c], [a, c, 0], [c, 0, a]);
  return v.map((p) => p.map((x) => x / Math.sqrt(3)));
})();
const MIN_CELL_SAMPLES = 3;
const MIN_RADIUS_UT = 15;

export const STILL_MAX_GYR_SD_RAD_S = 0.05;
export const STILL_MAX_ACC_SD_M_S2 = 0.3;
const G_M_S2 = 9.80665;
const DEG = Math.PI / 180;

/** Sphere coverage of magnetometer directions (figure-eight). */
export class SphereCoverage {
  constructor() {
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

  /** {cells reached, fraction of the 20}. */
  coverage() {
    const centre = this.lo.map((l, i) => (l + this.hi[i]) / 2);
    const counts = new Array(CELLS.length).fill(0);
    for (const m of this.samples) {
      const d = m.map((x, i) => x - centre[i]);
      const norm = Math.hypot(...d);
      if (!(norm >= MIN_RADIUS_UT)) continue;
      let best = 0;
      let bestDot = -Infinity;
      CELLS.forEach((c, k) => {
        const dot = (c[0] * d[0] + c[1] * d[1] + c[2] * d[2]) / norm;
        if (dot > bestDot) { bestDot = dot; best = k; }
      });
      counts[best] += 1;
    }
    const cells = counts.filter((n) => n >= MIN_CELL_SAMPLES).length;
    return { cells, fraction: cells / CELLS.length };
  }
}

function totalSd(window) {
  let sum = 0;
  for (let i = 0; i < 3; i++) {
    const mean = window.reduce((s, v) => s + v[i], 0) / window.length;
    sum += window.reduce((s, v) => s + (v[i] - mean) ** 2, 0) / window.length;
  }
  return Math.sqrt(sum);
}

/** Stillness of the last 0.5 s (postures): push acc (g) and gyro (°/s) samples of one sensor. */
export class Stillness {
  constructor(fsHz = 100, windowS = 0.5) {
    this.n = Math.max(2, Math.round(fsHz * windowS));
    this.acc = [];
    this.gyr = [];
    this.stillSamples = 0;
  }

  pushAcc(g) {
    this.acc.push(g.map((x) => x * G_M_S2));
    if (this.acc.length > this.n) this.acc.shift();
  }

  pushGyr(dps) {
    this.gyr.push(dps.map((x) => x * DEG));
    if (this.gyr.length > this.n) this.gyr.shift();
    if (this.still()) this.stillSamples += 1;
  }

  /** Whether the last window is still (false until a whole window has arrived). */
  still() {
    if (this.acc.length < this.n || this.gyr.length < this.n) return false;
    return totalSd(this.gyr) <= STILL_MAX_GYR_SD_RAD_S && totalSd(this.acc) <= STILL_MAX_ACC_SD_M_S2;
  }
}

/** Cycle count of the task from one sensor's gyroscope (°/s samples at fsHz). */
export class CycleCounter {
  constructor(fsHz = 100, { averageS = 0.3, riseDps = 60, fallDps = 20 } = {}) {
    this.window = [];
    this.n = Math.max(1, Math.round(fsHz * averageS));
    this.power = [0, 0, 0];
    this.rise = riseDps;
    this.fall = fallDps;
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
