// A live preview of knee flexion while the task is recorded: sagittal inclinations of thigh and shank from each
// sensor's tilt, the segments' axes from the protocol's two postures.  A preview only (shown as such): the
// server computes the knee angles of the report (orientation filters, magnetometer, Grood & Suntay).
//
// Segment axes in the sensor frame (ISB: x anterior, y proximal, z right), from the mean specific force of the
// two postures recorded before the task (at rest it points up):
//     y = f̄_standing / |f̄_standing|            (standing: both segments vertical)
//     x = normalise(f̄_supine − (f̄_supine·y) y)  (supine: the leg horizontal, its front up)      (P1)
//     z = x × y
// Tilt: the up direction u in the sensor frame (unit), carried by the gyroscope and pulled towards the
// measured specific force (a first-order complementary filter, time constant τ = 1 s, chosen a priori):
//     u ← u + (u × ω) Δt,   u ← normalise(u + (Δt/τ)(f/|f| − u))                               (P2)
// Sagittal inclination of a segment: α = atan2(u·x, u·y) (the segment turned by α about its z axis);
// knee flexion (shank turned by −flexion about z relative to the thigh):
//     flexion = α_thigh − α_shank                                                              (P3)
// Heading never enters (only tilt), so no magnetometer is needed; adduction and rotation are not previewed.
// The preview follows each gyroscope sample as it is decoded: its only delay is the air's and the filter's.

const G_M_S2 = 9.80665;
const DEG = Math.PI / 180;
const TAU_S = 1.0;

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const unit = (a) => { const n = Math.hypot(...a); return a.map((x) => x / n); };

/** Segment axes in the sensor frame (P1) from the mean specific force standing and supine (any unit). */
export function segmentAxes(standing, supine) {
  const y = unit(standing);
  const along = dot(supine, y);
  const x = unit(supine.map((v, i) => v - along * y[i]));
  return { x, y, z: cross(x, y) };
}

/** Mean of a posture's accelerometer samples (g), for segmentAxes. */
export class MeanForce {
  constructor() { this.sum = [0, 0, 0]; this.n = 0; }
  push(g) { g.forEach((v, i) => { this.sum[i] += v; }); this.n += 1; }
  mean() { return this.n ? this.sum.map((s) => s / this.n) : null; }
}

/** The tilt of one sensor (P2): push gyroscope (°/s) and accelerometer (g) samples in arrival order. */
export class Tilt {
  constructor(fsHz = 100) {
    this.dt = 1 / fsHz;
    this.u = null;
  }

  pushAcc(g) {
    const f = unit(g.map((x) => x * G_M_S2));
    if (!this.u) { this.u = f; return; }
    const k = this.dt / TAU_S;
    this.u = unit(this.u.map((x, i) => x + k * (f[i] - x)));
  }

  pushGyr(dps) {
    if (!this.u) return;
    const w = dps.map((x) => x * DEG);
    const c = cross(this.u, w);
    this.u = unit(this.u.map((x, i) => x + c[i] * this.dt));
  }

  /** Sagittal inclination of the segment with `axes`, radians (P3's α). */
  inclination(axes) {
    return Math.atan2(dot(this.u, axes.x), dot(this.u, axes.y));
  }
}

/** Knee flexion preview, degrees (P3), or null before both tilts and both calibrations exist. */
export function flexionDeg(tilts, axes) {
  if (!tilts.thigh?.u || !tilts.shank?.u || !axes.thigh || !axes.shank) return null;
  return (tilts.thigh.inclination(axes.thigh) - tilts.shank.inclination(axes.shank)) / DEG;
}
