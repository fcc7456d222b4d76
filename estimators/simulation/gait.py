r"""Level walking of both legs (thigh and shank) with heel-strike impacts, soft-tissue wobble and turns.

The sagittal joint kinematics follow published normative adult gait at self-selected speed:
D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley 2009, Appendix A
(the Table A.1–A.3 normal-cadence means; also *The Biomechanics and Motor Control of Human Gait*,
2nd ed., 1991, Fig. 4.x) and J. Perry & J. M. Burnfield, *Gait Analysis: Normal and Pathological
Function*, 2nd ed., SLACK 2010, Ch. 4 (knee) and Ch. 5 (hip).  The key frames below (% of the stride
from initial contact, degrees) are read off those curves; a periodic cubic spline through them is the
mean curve:

========================  ======================================  ========================================
event                     knee flexion (Winter / Perry)           thigh inclination (hip flexion, pelvis level)
========================  ======================================  ========================================
initial contact, 0 %      ~5°                                     ~+25°
loading response peak     15–20° at 12–15 %                       —
stance minimum            3–5° at ~40 %                           —
toe-off, ~60 %            ~35–40°                                 ~−8°
peak swing                60–65° at 70–73 %                       —
peak hip extension        —                                       ~−12° at ~55 %
peak hip flexion          —                                       ~+28° at ~85 %
========================  ======================================  ========================================

Model (per leg, side sign :math:`s = +1` right, :math:`-1` left, ISB segment frames as :mod:`.knee`)
------------------------------------------------------------------------------------------------------
* **Gait phase.**  Stride times :math:`T_k = \bar T(1 + c_T n_k)` (:math:`\bar T = 120/\mathrm{cadence}`,
  :math:`n_k \sim N(0,1)`, default CV 2 %, Hausdorff et al. 1995 report 1–3 % in healthy adults); the
  global phase :math:`p(t)` is a cubic spline through :math:`(t_k, k)` (C², monotone), the right leg's
  stride phase is :math:`p \bmod 1`, the left leg's :math:`(p - 0.5) \bmod 1`.  Initial contact (IC) of a
  leg is where its phase wraps, toe-off (TO) at 60 %.  Mid-swing is taken where the shank's sagittal
  angular rate peaks in swing (the event that shank-gyroscope detectors find, Aminian et al.,
  J Biomech 35:689, 2002); it falls at ~82 % of the stride with these curves, inside Perry's mid-swing (73–87 %).
* **Knee** (G1): :math:`\phi(t) = a(t)\,K(\text{phase}) + b(t)` with :math:`K` the normative curve and a
  per-stride amplitude :math:`a_k = 1 + c_a n_k` (default CV 3 %) and offset :math:`b_k` (SD 1°), splined
  across strides; adduction :math:`\alpha = 1° + 2°\sin(2\pi\,\text{phase} + 0.5)` (small swing varus),
  internal rotation :math:`\rho = -3° + 8°\,\phi/65°` (tibial rotation coupled with flexion).
* **Thigh** (G2): :math:`q_{earth,thigh} = R_z(\psi)\,q_{face} \otimes \exp_{ZXY}(H(\text{phase}),
  s\,\beta_h, s\,\rho_h)` with the inclination :math:`H`, hip adduction :math:`\beta_h = 4°\sin(2\pi\,
  \text{phase})` and hip rotation :math:`\rho_h = 4°\cos(2\pi\,\text{phase})`; the shank is the thigh
  times the knee quaternion (K1).
* **Pelvis and hips** (G3): the pelvis moves at ``speed_m_s`` along the heading :math:`\psi(t)` (constant,
  or turning by 180° over ``turn_duration_s`` with a minimum-jerk profile), rises and falls by 2 cm twice
  per stride (lowest at double support) and sways 2 cm to the stance side.  The hip joint centres sit
  9 cm either side; the knee is :math:`hip + R_{thigh}[0, -L_t, 0]`.  The foot is not constrained to the
  floor: the segment *rotations* are normative, the translations only approximate (what orientation
  filters see is dominated by rotation, gravity and the impacts).
* **Heel-strike impact** (G4): at each IC of the leg the skin point carrying a sensor is displaced along
  :math:`u = (-0.3, 1, 0)/|\cdot|` (mostly axial, in segment coordinates) by
  :math:`d(\tau) = A\,e(\tau/\tau_i)\sin(2\pi f_i\tau)`, :math:`e(x) = x^3 e^{3(1-x)}` (C² at the onset,
  peak 1 at :math:`x = 1`), :math:`f_i = 20` Hz, :math:`\tau_i = 12` ms; :math:`A` is chosen so that the
  transient's peak acceleration :math:`\max|\ddot d|` is ``shank_impact_g`` (default 4.5 g; reported
  3–6 g at the tibia in walking, Lafortune & Hennig, J Biomech 25:1992) or ``thigh_impact_g``
  (default 1.5 g).
* **Soft-tissue wobble** (G5): the same skin point turns relative to the bone by
  :math:`\theta(\tau) = W\,e(\tau/\tau_w)\sin(2\pi f_w\tau)` about ``wobble_axis`` (segment coordinates),
  normalised so that :math:`\max|\theta| = W` exactly (``*_wobble_rad``, default 2°); :math:`f_w` = 10 Hz
  (thigh) / 14 Hz (shank), :math:`\tau_w` = 40 ms: a damped oscillation of 0.2–0.3 s after each heel
  strike (soft-tissue artefact frequencies 5–20 Hz, Wakeling & Nigg 2001).

The mounting trajectories :attr:`GaitLeg.thigh_mount` / :attr:`GaitLeg.shank_mount` are the skin point
(position = segment origin + lever arm + impact displacement; orientation = segment ⊗ wobble): pass them
to :func:`estimators.simulation.simulate` with the sensor's rotation on the skin, or use
:func:`simulate_leg`.  The truth knee angles are those of the *bones* (the segments), so wobble is an
error that no orientation filter can remove.

Truth: :attr:`GaitLeg.motion` is a :class:`~estimators.simulation.knee.LegMotion` whose ``cycles_s`` are
the complete strides inside the clip, ``[IC_k, IC_{k+1}]``, and ``phases_s`` the events per stride
(IC, TO, mid-swing, next IC); all ICs, TOs and mid-swings inside the clip are in ``*_s`` arrays.

Example
-------
>>> from estimators.simulation import gait
>>> walk = gait.walking(10.0, turn_at_s=4.0, seed=1)            # both legs, in motion from t = 0
>>> thigh, shank = gait.simulate_leg(walk.right, seed=1)         # SimulatedImu each (acc, gyr, mag)
>>> g_t, g_s = thigh.on_grid(), shank.on_grid()                  # 100 Hz grids + sensor truth
>>> flexion_rad = walk.right.knee_angles_at(g_t.t_true_s)[:, 0]  # bone truth on the grid
>>> walk.right.motion.phases_s.shape[1]                          # IC, TO, mid-swing, next IC
4

``python -m benchmarks.walking`` scores the orientation methods on these clips.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimators import quaternion as quat
from estimators.knee import knee_quaternion, side_sign
from estimators.simulation.imu import SimulatedImu, simulate
from estimators.simulation.knee import THIGH_LENGTH_M, LegMotion, segment_frame
from estimators.simulation.spec import GRAVITY_M_S2, ImuSpec
from estimators.simulation.trajectory import DEFAULT_FS_HZ, Trajectory, intrinsic_rotation, min_jerk, time_grid

FloatArray = NDArray[np.float64]

__all__ = ["GaitLeg", "GaitMotion", "HIP_KEYFRAMES_DEG", "KNEE_KEYFRAMES_DEG", "TOE_OFF_FRACTION",
           "lateral_mounting", "normative_hip_rad", "normative_knee_rad", "simulate_leg", "walking"]

#: (% of stride, knee flexion °): Winter 2009 App. A / Perry & Burnfield 2010 Ch. 4 normal adult means.
KNEE_KEYFRAMES_DEG = np.array([
    (0.0, 5.0), (6.0, 11.0), (13.0, 18.5), (22.0, 13.0), (32.0, 6.0), (40.0, 4.0), (48.0, 9.0),
    (55.0, 22.0), (60.0, 37.0), (66.0, 55.0), (72.0, 62.5), (78.0, 56.0), (85.0, 36.0), (92.0, 14.0),
    (97.0, 5.0),
])
#: (% of stride, thigh inclination / hip flexion °, pelvis level): Winter 2009 App. A, Perry 2010 Ch. 5.
HIP_KEYFRAMES_DEG = np.array([
    (0.0, 25.0), (12.0, 21.0), (30.0, 8.0), (45.0, -5.0), (55.0, -12.0), (62.0, -8.0), (75.0, 15.0),
    (86.0, 28.0), (94.0, 27.0),
])
TOE_OFF_FRACTION = 0.60
HIP_HALF_WIDTH_M = 0.09
PELVIS_HEIGHT_M = 0.92

_IMPACT_FREQ_HZ, _IMPACT_TAU_S = 20.0, 0.012
_WOBBLE_TAU_S = 0.04
_WOBBLE_FREQ_HZ = {"thigh": 10.0, "shank": 14.0}
_IMPACT_DIR = np.array([-0.3, 1.0, 0.0]) / np.hypot(0.3, 1.0)


def _periodic_curve(keyframes_deg: FloatArray):
    from scipy.interpolate import CubicSpline

    x = np.append(keyframes_deg[:, 0], 100.0) / 100.0
    y = np.deg2rad(np.append(keyframes_deg[:, 1], keyframes_deg[0, 1]))
    return CubicSpline(x, y, bc_type="periodic")


def normative_knee_rad(phase: ArrayLike) -> FloatArray:
    """Mean normative knee flexion (rad) at stride phase ``phase`` in [0, 1) (0 = initial contact), (G1)."""
    return _periodic_curve(KNEE_KEYFRAMES_DEG)(np.mod(np.asarray(phase, dtype=np.float64), 1.0))


def _knee_curve(keyframes_deg: ArrayLike):
    """The mean knee curve (phase → rad) through other key frames (``walking(knee_keyframes_deg=...)``)."""
    k = np.asarray(keyframes_deg, dtype=np.float64)
    if k.ndim != 2 or k.shape[1] != 2 or len(k) < 4 or not np.all(np.isfinite(k)) or k[0, 0] < 0.0 \
            or k[-1, 0] >= 100.0 or np.any(np.diff(k[:, 0]) <= 0.0):
        raise ValueError("knee_keyframes_deg must be (K >= 4, 2) finite rows (% of the stride, degrees) with the % "
                         f"strictly increasing in [0, 100), got {keyframes_deg!r}")
    spline = _periodic_curve(k)
    return lambda phase: spline(np.mod(np.asarray(phase, dtype=np.float64), 1.0))


def normative_hip_rad(phase: ArrayLike) -> FloatArray:
    """Mean normative thigh inclination / hip flexion (rad) at stride phase ``phase`` (G2)."""
    return _periodic_curve(HIP_KEYFRAMES_DEG)(np.mod(np.asarray(phase, dtype=np.float64), 1.0))


def _envelope(x: FloatArray) -> FloatArray:
    """:math:`e(x) = x^3 e^{3(1-x)}` for x >= 0, 0 before: C² at the onset, peak 1 at x = 1."""
    xp = np.clip(x, 0.0, None)
    return np.where(x > 0.0, xp**3 * np.exp(3.0 * (1.0 - xp)), 0.0)


def _transient(t: FloatArray, onsets_s: FloatArray, freq_hz: float, tau_s: float) -> FloatArray:
    """Sum over onsets of e((t−t₀)/τ) sin(2πf(t−t₀)) (unit-amplitude shape of G4/G5), cut 12 τ after each."""
    out = np.zeros_like(t)
    for t0 in onsets_s:
        sel = (t > t0) & (t < t0 + 12.0 * tau_s + 3.0 / freq_hz)
        tau = t[sel] - t0
        out[sel] += _envelope(tau / tau_s) * np.sin(2.0 * np.pi * freq_hz * tau)
    return out


def _shape_peak(freq_hz: float, tau_s: float, derivative: int) -> float:
    """max |d^k/dτ^k e(τ/τ_s) sin(2πfτ)| on a fine grid (k = 0 or 2): the scale that makes amplitudes exact."""
    tau = np.linspace(0.0, 12.0 * tau_s + 3.0 / freq_hz, 20001)
    y = _envelope(tau / tau_s) * np.sin(2.0 * np.pi * freq_hz * tau)
    if derivative == 2:
        y = np.gradient(np.gradient(y, tau), tau)
    return float(np.max(np.abs(y)))


@dataclass(frozen=True, eq=False)
class GaitLeg:
    """One leg during the walk: bones, sensor-carrying skin points, true knee angles and gait events.

    side : ``"right"`` or ``"left"``.
    motion : :class:`LegMotion` of the bones (ISB segments, true Grood & Suntay knee angles); its
        ``cycles_s`` (K, 2) are the complete strides ``[IC_k, IC_{k+1}]`` inside the clip and ``phases_s``
        (K, 4) their events: initial contact, toe-off, mid-swing, next initial contact (s).
    thigh_mount, shank_mount : :class:`Trajectory` of the skin point under each sensor (G4, G5).
    initial_contact_s, toe_off_s, mid_swing_s : every such event of this leg inside the clip, s.
    thigh_impact_g, shank_impact_g : peak acceleration of the heel-strike transient, g.
    thigh_wobble_rad, shank_wobble_rad : peak soft-tissue rotation after each heel strike, rad.
    wobble_axis : (3,) unit axis of the wobble in segment coordinates.
    """

    side: str
    motion: LegMotion
    thigh_mount: Trajectory
    shank_mount: Trajectory
    initial_contact_s: FloatArray
    toe_off_s: FloatArray
    mid_swing_s: FloatArray
    thigh_impact_g: float
    shank_impact_g: float
    thigh_wobble_rad: float
    shank_wobble_rad: float
    wobble_axis: FloatArray

    def knee_angles_at(self, t_s: ArrayLike) -> FloatArray:
        """True (bone) knee angles (n, 3), rad: flexion, adduction, internal rotation."""
        return self.motion.knee_angles_at(t_s)


@dataclass(frozen=True, eq=False)
class GaitMotion:
    """Result of :func:`walking`: both legs of one walk.

    t_s : (M,) dense true times, s.   right, left : :class:`GaitLeg`.
    stride_time_s : (K,) the stride durations drawn (global phase), s.   cadence_steps_min, speed_m_s : as asked.
    heading_rad : (M,) ENU yaw of the walking direction.   turn_s : (2,) start and end of the turn, or None.
    """

    t_s: FloatArray
    right: GaitLeg
    left: GaitLeg
    stride_time_s: FloatArray
    cadence_steps_min: float
    speed_m_s: float
    heading_rad: FloatArray
    turn_s: FloatArray | None

    def leg(self, side: str) -> GaitLeg:
        side_sign(side)
        return self.right if side == "right" else self.left


def _positive(name: str, value: float, lo: float, hi: float) -> float:
    if not (np.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{name} must be between {lo} and {hi}, got {value!r}")
    return float(value)


def walking(
    duration_s: float = 10.0,
    *,
    cadence_steps_min: float = 110.0,
    speed_m_s: float = 1.3,
    facing_rad: float = 0.0,
    start_phase: float | None = None,
    stride_cv: float = 0.02,
    amplitude_cv: float = 0.03,
    offset_sd_rad: float = float(np.deg2rad(1.0)),
    shank_impact_g: float = 4.5,
    thigh_impact_g: float = 1.5,
    shank_wobble_rad: float = float(np.deg2rad(2.0)),
    thigh_wobble_rad: float = float(np.deg2rad(2.0)),
    wobble_axis: ArrayLike = (1.0, 0.5, 1.0),
    turn_at_s: float | None = None,
    turn_duration_s: float = 2.0,
    standing_start_s: float = 0.0,
    knee_keyframes_deg: ArrayLike | None = None,
    seed: int | np.random.Generator | None = 0,
    fs_hz: float = DEFAULT_FS_HZ,
    knee_gain: dict[str, float] | None = None,
) -> GaitMotion:
    """Level walking of both legs (G1–G5, module docstring), in motion from the first sample by default.

    duration_s : clip length, s (2–600).   cadence_steps_min : steps per minute (60–160; stride = 120/cadence s).
    speed_m_s : walking speed (0.3–2.5 m/s).   facing_rad : initial ENU yaw of the walking direction.
    start_phase : global stride phase at t = 0 (None: drawn uniformly, so clips start anywhere in the cycle).
    stride_cv, amplitude_cv : stride-to-stride CV of stride time and of knee/hip amplitude.
    offset_sd_rad : stride-to-stride SD of the knee flexion offset, rad.
    shank_impact_g, thigh_impact_g : heel-strike transient peak, g (G4; 0 switches it off).
    shank_wobble_rad, thigh_wobble_rad : soft-tissue wobble peak, rad (G5; 0 switches it off).
    wobble_axis : (3,) wobble axis in segment coordinates (normalised here).
    turn_at_s : start of a 180° turn (to the left), s, or None.   turn_duration_s : its length, s.
    standing_start_s : stand still this long first (knee straight), then start walking over one stride.
    knee_keyframes_deg : (K, 2) (% of the stride from IC, knee flexion °) replacing :data:`KNEE_KEYFRAMES_DEG`
        (K ≥ 4, % strictly increasing in [0, 100)): another mean knee curve, e.g. a stiff-knee pattern; the
        periodic spline through it is the mean curve (G1); toe-off stays at 60 %.
    seed : random draws (stride times, amplitudes, start phase).   fs_hz : dense grid rate.
    knee_gain : ``{side: g}`` multiplies that leg's walking knee flexion (G1) by ``g`` (0.3–1.5; default 1): a
        known asymmetry, e.g. ``{"left": 0.8}`` gives every left flexion peak and ROM 80 % of the same stride's
        right value (the same random draws for both legs), for limb-symmetry tests.
    """
    duration_s = _positive("duration_s", duration_s, 2.0, 600.0)
    cadence = _positive("cadence_steps_min", cadence_steps_min, 60.0, 160.0)
    speed = _positive("speed_m_s", speed_m_s, 0.3, 2.5)
    for name, v, hi in (("stride_cv", stride_cv, 0.1), ("amplitude_cv", amplitude_cv, 0.2),
                        ("offset_sd_rad", offset_sd_rad, 0.2), ("shank_impact_g", shank_impact_g, 15.0),
                        ("thigh_impact_g", thigh_impact_g, 15.0), ("shank_wobble_rad", shank_wobble_rad, 0.2),
                        ("thigh_wobble_rad", thigh_wobble_rad, 0.2), ("standing_start_s", standing_start_s, 60.0)):
        _positive(name, v, 0.0, hi)
    knee_curve = normative_knee_rad if knee_keyframes_deg is None else _knee_curve(knee_keyframes_deg)
    axis = np.asarray(wobble_axis, dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(axis)) or np.linalg.norm(axis) == 0.0:
        raise ValueError(f"wobble_axis must be a finite non-zero 3-vector, got {wobble_axis!r}")
    axis = axis / np.linalg.norm(axis)
    rng = np.random.default_rng(seed)
    p0 = float(rng.uniform(0.0, 1.0)) if start_phase is None else float(start_phase) % 1.0
    stride_mean_s = 120.0 / cadence
    t = time_grid(duration_s, fs_hz)

    # (G1) global phase through stride boundaries; ramp from standing
    ramp_s = stride_mean_s
    walk0 = float(standing_start_s)
    n_str = int(np.ceil((duration_s - walk0) / stride_mean_s)) + 4
    strides = stride_mean_s * (1.0 + stride_cv * rng.standard_normal(n_str))
    strides = np.clip(strides, 0.8 * stride_mean_s, 1.2 * stride_mean_s)
    knots_t = walk0 - p0 * strides[0] + np.concatenate([[0.0], np.cumsum(strides)]) - strides[0]
    knots_p = np.arange(len(knots_t), dtype=np.float64) - 1.0
    from scipy.interpolate import CubicSpline

    phase_spline = CubicSpline(knots_t, knots_p)
    beta = np.ones_like(t) if walk0 == 0.0 else min_jerk((t - walk0) / ramp_s)
    p_global = phase_spline(np.maximum(t, walk0))  # frozen while standing
    # per-stride amplitude and offset, splined at stride middles (C²)
    mids = 0.5 * (knots_t[1:] + knots_t[:-1])
    amp_k = 1.0 + amplitude_cv * rng.standard_normal(len(mids))
    off_k = offset_sd_rad * rng.standard_normal(len(mids))
    amp = CubicSpline(mids, amp_k)(t)
    off = CubicSpline(mids, off_k)(t)

    # (G3) heading, pelvis
    if turn_at_s is None:
        psi = np.full_like(t, float(facing_rad))
        turn = None
    else:
        _positive("turn_duration_s", turn_duration_s, 0.5, 10.0)
        psi = facing_rad + np.pi * min_jerk((t - turn_at_s) / turn_duration_s)
        turn = np.array([float(turn_at_s), float(turn_at_s) + turn_duration_s])
    fwd = np.column_stack([np.cos(psi), np.sin(psi), np.zeros_like(t)])
    up = np.array([0.0, 0.0, 1.0])
    right_dir = np.cross(fwd, up)
    v = speed * beta
    vel = v[:, None] * fwd
    dist = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (vel[1:] + vel[:-1]) * np.diff(t)[:, None], axis=0)])
    pr = np.mod(p_global, 1.0)
    pelvis = dist + up * (PELVIS_HEIGHT_M - beta * 0.02 * np.cos(4.0 * np.pi * pr))[:, None] \
        + right_dir * (beta * 0.02 * np.sin(2.0 * np.pi * pr))[:, None]
    q_face = quat.multiply(quat.from_axis_angle(up, psi), segment_frame(0.0, "standing"))

    gains = {"right": 1.0, "left": 1.0}
    for side, g in (knee_gain or {}).items():
        side_sign(side)
        gains[side] = _positive(f"knee_gain[{side!r}]", g, 0.3, 1.5)
    legs = {}
    for side, lag in (("right", 0.0), ("left", 0.5)):
        s = side_sign(side)
        ph = np.mod(p_global - lag, 1.0)
        flex = beta * gains[side] * (amp * knee_curve(ph) + off) + (1.0 - beta) * np.deg2rad(2.0)
        add = beta * np.deg2rad(1.0 + 2.0 * np.sin(2.0 * np.pi * ph + 0.5))
        rot = np.deg2rad(-3.0) + np.deg2rad(8.0) * flex / np.deg2rad(65.0)
        knee_ang = np.column_stack([flex, add, rot])
        hip = np.column_stack([beta * amp * normative_hip_rad(ph),
                               s * beta * np.deg2rad(4.0) * np.sin(2.0 * np.pi * ph),
                               s * beta * np.deg2rad(4.0) * np.cos(2.0 * np.pi * ph)])
        q_thigh = quat.multiply(q_face, intrinsic_rotation(hip, "ZXY"))
        q_shank = quat.multiply(q_thigh, knee_quaternion(knee_ang, side))
        hip_pos = pelvis + s * HIP_HALF_WIDTH_M * right_dir
        knee_pos = hip_pos + quat.rotate(q_thigh, np.array([0.0, -THIGH_LENGTH_M, 0.0]))
        thigh = Trajectory(t, q_thigh, hip_pos)
        shank = Trajectory(t, q_shank, knee_pos)

        # events: phase wraps (IC) and 60 % (TO) from the phase spline's knots, after the walk start
        k_all = np.arange(np.floor(knots_p[0]), np.ceil(knots_p[-1]) + 1)
        ic = _phase_times(phase_spline, knots_t, k_all + lag)
        to = _phase_times(phase_spline, knots_t, k_all + lag + TOE_OFF_FRACTION)
        t_ok = walk0 + (ramp_s if walk0 > 0.0 else 0.0)
        ic = ic[(ic >= t_ok) & (ic <= t[-1])]
        to = to[(to >= t_ok) & (to <= t[-1])]
        # mid-swing: peak sagittal shank rate between TO and the next IC (from the truth)
        w_z = shank.angular_velocity(t)[:, 2]
        ms = []
        for t_to in to:
            nxt = ic[ic > t_to]
            t_end = nxt[0] if len(nxt) else t_to + (1.0 - TOE_OFF_FRACTION) * stride_mean_s
            sel = (t >= t_to) & (t <= min(t_end, t[-1]))
            if nxt.size and sel.sum() > 2:
                ms.append(t[sel][np.argmax(np.abs(w_z[sel]))])
        ms = np.asarray(ms)
        cycles, phases = [], []
        for a, b in zip(ic[:-1], ic[1:]):
            tos, mss = to[(to > a) & (to < b)], ms[(ms > a) & (ms < b)]
            if len(tos) == 1 and len(mss) == 1:
                cycles.append((a, b))
                phases.append((a, tos[0], mss[0], b))
        motion = LegMotion(t, thigh, shank, knee_ang, side, np.array([0.0, -0.21, 0.08 * s]),
                           np.array([0.03, -0.12, 0.05 * s]), np.reshape(cycles, (-1, 2)),
                           np.reshape(phases, (-1, 4)))

        ic_all = _phase_times(phase_spline, knots_t, k_all + lag)
        ic_all = ic_all[(ic_all > walk0) & (ic_all < t[-1])]
        ic_w = ic_all
        scale_ic = np.interp(ic_w, t, beta)  # impacts grow with the walking ramp
        mounts = []
        for seg, traj, lever, g_peak, w_peak in (
                ("thigh", thigh, motion.thigh_lever_arm_m, thigh_impact_g, thigh_wobble_rad),
                ("shank", shank, motion.shank_lever_arm_m, shank_impact_g, shank_wobble_rad)):
            imp = np.zeros_like(t)
            wob = np.zeros_like(t)
            for t0, sc in zip(ic_w, scale_ic):
                imp += sc * _transient(t, np.array([t0]), _IMPACT_FREQ_HZ, _IMPACT_TAU_S)
                wob += sc * _transient(t, np.array([t0]), _WOBBLE_FREQ_HZ[seg], _WOBBLE_TAU_S)
            a_imp = g_peak * GRAVITY_M_S2 / _shape_peak(_IMPACT_FREQ_HZ, _IMPACT_TAU_S, 2)
            a_wob = w_peak / _shape_peak(_WOBBLE_FREQ_HZ[seg], _WOBBLE_TAU_S, 0)
            q_m = quat.multiply(traj.q_earth_body, quat.from_axis_angle(axis, a_wob * wob))
            offset_seg = lever[None, :] + (a_imp * imp)[:, None] * _IMPACT_DIR[None, :]
            p_m = traj.pos_m + quat.rotate(traj.q_earth_body, offset_seg)
            mounts.append(Trajectory(t, q_m, p_m))
        legs[side] = GaitLeg(side, motion, mounts[0], mounts[1], ic, to, ms, float(thigh_impact_g),
                             float(shank_impact_g), float(thigh_wobble_rad), float(shank_wobble_rad), axis)

    return GaitMotion(t, legs["right"], legs["left"], strides, cadence, speed, psi, turn)


def _phase_times(spline, knots_t: FloatArray, phases: FloatArray) -> FloatArray:
    """Times where the (monotone) phase spline reaches each value (inverted on a 0.1 ms grid)."""
    tt = np.arange(knots_t[0], knots_t[-1], 1e-4)
    pp = spline(tt)
    keep = (phases >= pp[0]) & (phases <= pp[-1])
    return np.interp(phases[keep], pp, tt)


def lateral_mounting(side: str, misalignment_rad: float = 0.0,
                     seed: int | np.random.Generator | None = None) -> tuple[FloatArray, FloatArray]:
    """``(q_thigh_sensor, q_shank_sensor)`` skin → sensor rotations of sensors strapped on the lateral side.

    The sensor's x axis points up the segment (proximal), its z axis out of the skin (laterally: +z of
    the segment on the right leg, −z on the left), y = z × x; then each is turned by a random rotation
    of up to ``misalignment_rad`` (:func:`~estimators.simulation.random_rotation`)."""
    from estimators.simulation.spec import random_rotation

    s = side_sign(side)
    rng = np.random.default_rng(seed)
    x_s, z_s = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, s])
    base = quat.from_matrix(np.column_stack([x_s, np.cross(z_s, x_s), z_s]))
    return tuple(quat.multiply(base, random_rotation(misalignment_rad, rng)) for _ in range(2))


def simulate_leg(leg: GaitLeg, spec_thigh: ImuSpec | None = None, spec_shank: ImuSpec | None = None, *,
                 q_thigh_sensor: ArrayLike | None = None, q_shank_sensor: ArrayLike | None = None,
                 seed: int | None = 0, **kwargs) -> tuple[SimulatedImu, SimulatedImu]:
    """Thigh and shank sensors of one leg (:func:`estimators.simulation.simulate` on the mount trajectories).

    ``q_*_sensor``: rotation skin → sensor (default :func:`lateral_mounting` without misalignment).  The
    returned ``SimulatedImu.segment`` is the *skin point* (bone ⊗ wobble); the bone truth is
    ``leg.motion.thigh`` / ``leg.motion.shank``.  The sensor-to-bone rotation without wobble is the same
    ``q_*_sensor``.  Extra keyword arguments go to ``simulate`` (``mag_earth_ut``, ...).
    """
    default = lateral_mounting(leg.side)
    q_t = default[0] if q_thigh_sensor is None else q_thigh_sensor
    q_s = default[1] if q_shank_sensor is None else q_shank_sensor
    seeds = np.random.SeedSequence(seed).spawn(2)
    thigh = simulate(leg.thigh_mount, spec_thigh, q_segment_sensor=q_t, seed=np.random.default_rng(seeds[0]),
                     **kwargs)
    shank = simulate(leg.shank_mount, spec_shank, q_segment_sensor=q_s, seed=np.random.default_rng(seeds[1]),
                     **kwargs)
    return thigh, shank
