// A live preview of the three knee angles while the task is recorded, computed in the browser from the raw
// samples as they arrive.  A preview only (the page says so): the report's angles are the server's (its orientation
// filter with the magnetometer, the accelerometer's bias removed, the stillest posture windows, heading choice).
// The preview keeps the report's convention — Grood & Suntay, the same names, order and signs, the left leg mirrored
// (estimators/knee.py K1/K2, the project's one definition; the names and order are static/charts.js ANGLES) —
// and this is what it computes, and what it leaves out:
//
// Segment axes in the sensor frame (ISB: x anterior, y proximal, z right), from the mean specific force of the
// two postures recorded before the task in this visit (at rest it points up; estimators/knee.py eqs. 8.1–8.8):
//     y = f̄_standing / |f̄_standing|            (standing: both segments vertical)
//     x = normalise(f̄_supine − (f̄_supine·y) y)  (supine: the leg horizontal, its front up)      (P1)
//     z = x × y,   R_sensor,segment = [x y z]
// (the posture's mean over the whole step, not the server's stillest 5 s; the accelerometer's bias is not removed).
// Gyroscope bias: the mean gyroscope of the same two postures (still), per sensor, subtracted from the task's.
//
// Attitude of each sensor, 6D (no magnetometer): R_earth,sensor carried by the gyroscope and pulled towards the
// measured specific force by a first-order complementary filter (time constant τ = 1 s, chosen a priori):
//     R ← R · exp([ω − b]× Δt)                                     (gyroscope, each sample)
//     R ← exp([ê × ẑ]× · (Δt/τ) · ∠(ê, ẑ)) · R,  ê = R f/|f|         (accelerometer, each sample)         (P2)
// The correction turns about a horizontal axis: it fixes the tilt and never the heading, which each sensor keeps
// from its own start (arbitrary).  Segment attitude: R_earth,segment = R_earth,sensor · R_sensor,segment (6.1').
//
// Relative heading: without a shared magnetic north the two earth frames differ by a turn δ about the vertical.
// δ is the knee's hinge constraint (estimators/knee.py H2: the flexion axes z of femur and tibia parallel),
// its sums weighted by exp(−age / τ_h), τ_h = 10 s (a few step-up cycles, so that the hinge's bias from the true
// adduction and rotation averages out; short enough to follow the gyroscopes' remaining heading drift):
//     S ← λS + (ẑ_t,x ẑ_f,y − ẑ_t,y ẑ_f,x),  C ← λC + (ẑ_t,x ẑ_f,x + ẑ_t,y ẑ_f,y),  δ = atan2(S, C)     (P3)
// Knee: R_femur,tibia = R_earth,femurᵀ · R_z(δ) · R_earth,tibia (6.2'), and Grood & Suntay's angles (K2):
//     s·adduction = asin R₂₁,  −flexion = atan2(−R₀₁, R₁₁),  s·rotation = atan2(−R₂₀, R₂₂),  s = +1 right, −1 left
//
// Limits, so what the preview can and cannot show: flexion is observable from tilt alone; adduction and rotation need
// the two segments' relative heading, which 6D cannot measure, so the hinge assumption (P3) sets it: the preview's
// rotation is the rotation relative to the mean the hinge fit absorbs over the last ~τ_h (the rotation about a
// vertical shank is indistinguishable from a heading offset), and fast accelerations (heel strikes) tilt both
// sensors' vertical for up to ~τ.  The preview follows each sample as it is decoded: its only delay is the air's and
// the filter's.

const G_M_S2 = 9.80665;
const DEG = Math.PI / 180;
const TAU_S = 1.0;
const HINGE_TAU_S = 10.0;

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const unit = (a) => { const n = Math.hypot(...a); return a.map((x) => x / n); };
// 3 × 3 matrices as arrays of rows
const mul = (a, b) => a.map((row) => [0, 1, 2].map((j) => row[0] * b[0][j] + row[1] * b[1][j] + row[2] * b[2][j]));
const transpose = (a) => [0, 1, 2].map((i) => [a[0][i], a[1][i], a[2][i]]);
const apply = (a, v) => a.map((row) => dot(row, v));

/** The rotation matrix of angle |v| about v/|v| (Rodrigues), identity for v = 0. */
function rotation(v) {
  const th = Math.hypot(...v);
  if (th < 1e-12) return [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
  const [x, y, z] = v.map((c) => c / th);
  const c = Math.cos(th);
  const s = Math.sin(th);
  const C = 1 - c;
  return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
    [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
    [z * x * C - y * s, z * y * C + x * s, c + z * z * C]];
}

/** Re-orthonormalise a rotation matrix (rows), against the rounding of many small products. */
function orthonormal(r) {
  const x = unit(r[0]);
  const z = unit(cross(x, r[1]));
  return [x, cross(z, x), z];
}

/** Segment axes in the sensor frame (P1) from the mean specific force standing and supine (any unit). */
export function segmentAxes(standing, supine) {
  const y = unit(standing);
  const along = dot(supine, y);
  const x = unit(supine.map((v, i) => v - along * y[i]));
  return { x, y, z: cross(x, y) };
}

/** Mean of a posture's samples (accelerometer in g, gyroscope in °/s), for segmentAxes and the gyroscope's bias. */
export class MeanForce {
  constructor() { this.sum = [0, 0, 0]; this.n = 0; }
  push(v) { v.forEach((x, i) => { this.sum[i] += x; }); this.n += 1; }
  mean() { return this.n ? this.sum.map((s) => s / this.n) : null; }
}

/** The 6D attitude of one sensor (P2): push gyroscope (°/s) and accelerometer (g) samples in arrival order.
 * biasDps: the gyroscope's bias (°/s) subtracted from every sample. */
export class Attitude {
  constructor(fsHz = 100, biasDps = [0, 0, 0]) {
    this.dt = 1 / fsHz;
    this.bias = biasDps;
    this.r = null;          // R_earth,sensor (rows), null before the first accelerometer sample
  }

  pushAcc(g) {
    const f = unit(g);
    if (!this.r) {
      // the turn that takes f onto the vertical (no heading: the sensor's own start)
      const axis = cross(f, [0, 0, 1]);
      const s = Math.hypot(...axis);
      const angle = Math.atan2(s, f[2]);
      this.r = rotation(s < 1e-12 ? [angle, 0, 0] : axis.map((a) => (a / s) * angle));
      return;
    }
    const e = apply(this.r, f);
    const axis = cross(e, [0, 0, 1]);
    const s = Math.hypot(...axis);
    if (s < 1e-12) return;
    const angle = Math.atan2(s, e[2]) * (this.dt / TAU_S);
    this.r = mul(rotation(axis.map((a) => (a / s) * angle)), this.r);
  }

  pushGyr(dps) {
    if (!this.r) return;
    this.r = orthonormal(mul(this.r, rotation(dps.map((x, i) => (x - this.bias[i]) * DEG * this.dt))));
  }
}

/** The knee's preview from both sensors' samples (P1–P3).  axes: {thigh, shank} of segmentAxes; biasDps: {thigh,
 * shank} gyroscope bias (°/s); side: "right" or "left" (the patient's knee: the left mirrored, K2's s). */
export class KneePreview {
  constructor(axes, biasDps, side, fsHz = 100) {
    this.side = side === "left" ? -1 : 1;
    this.seg = {};
    this.att = {};
    for (const s of ["thigh", "shank"]) {
      const { x, y, z } = axes[s];
      this.seg[s] = [0, 1, 2].map((i) => [x[i], y[i], z[i]]);    // R_sensor,segment: the axes as columns
      this.att[s] = new Attitude(fsHz, biasDps[s] ?? [0, 0, 0]);
    }
    this.lambda = Math.exp(-1 / (fsHz * HINGE_TAU_S));
    this.hinge = [0, 0];
  }

  pushAcc(segment, g) { this.att[segment].pushAcc(g.map((x) => x * G_M_S2)); }

  pushGyr(segment, dps) {
    this.att[segment].pushGyr(dps);
    if (segment === "shank") this.updateHinge();
  }

  /** A sensor's stream restarts (a reconnection after a drop: the motion of the gap was never seen): its attitude
   * starts again from its next accelerometer sample, with a heading of its own, so the hinge's sums start again. */
  restart(segment) {
    this.att[segment].r = null;
    this.hinge = [0, 0];
  }

  segment(s) { return mul(this.att[s].r, this.seg[s]); }

  ready() { return Boolean(this.att.thigh.r && this.att.shank.r); }

  // (P3), once per shank gyroscope sample
  updateHinge() {
    if (!this.ready()) return;
    const zf = transpose(this.segment("thigh"))[2];
    const zt = transpose(this.segment("shank"))[2];
    this.hinge[0] = this.lambda * this.hinge[0] + (zt[0] * zf[1] - zt[1] * zf[0]);
    this.hinge[1] = this.lambda * this.hinge[1] + (zt[0] * zf[0] + zt[1] * zf[1]);
  }

  /** [flexion, adduction, internal rotation] in degrees (ANGLES' order, clinical signs), or null before both
   * sensors' first samples. */
  angles() {
    if (!this.ready()) return null;
    const delta = Math.atan2(this.hinge[0], this.hinge[1]);
    const c = Math.cos(delta);
    const s = Math.sin(delta);
    const rz = [[c, -s, 0], [s, c, 0], [0, 0, 1]];
    const r = mul(transpose(this.segment("thigh")), mul(rz, this.segment("shank")));
    const add = Math.asin(Math.max(-1, Math.min(1, r[2][1])));
    const flex = -Math.atan2(-r[0][1], r[1][1]);
    const rot = Math.atan2(-r[2][0], r[2][2]);
    return [flex / DEG, (this.side * add) / DEG, (this.side * rot) / DEG];
  }
}
