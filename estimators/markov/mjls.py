r"""Markov jump linear system (MJLS) filter for a planar multi-segment limb (seed 002; seed 000 §2.2).

Nogueira, Siqueira, Inoue, Terra (2014), *Sensors* 14, 1835: four segments — trunk B, thigh T,
shank S, foot F — each with an IMU giving a sagittal rate :math:`\omega_i` and an accelerometer angle
:math:`\hat\theta_{a,i}` (eq. 9), and encoders at the hip, knee and ankle giving the relative angles
:math:`\alpha_h = \theta_B-\theta_T`, :math:`\alpha_k = \theta_T-\theta_S`, :math:`\alpha_a = \theta_S-\theta_F`.

Markovian Kalman filter (MKF, eqs. 14–30)
-----------------------------------------
State (eq. 16) :math:`x = [\Delta\theta_B, \Delta b_B, \dots, \Delta\theta_F, \Delta b_F]`, block-diagonal
:math:`\bar A` with :math:`-1/\tau_{g,i}` (eq. 18), :math:`\bar B = I`; output (eqs. 17–18)

.. math:: y = [\Delta_{IMU},\ \Delta_h,\ \Delta_k,\ \Delta_a]^T,\qquad
          \bar C(\Theta) = \begin{bmatrix} M_B & 0 & M_T & 0 & M_S & 0 & M_F & 0\\
          1&0&-1&0&0&0&0&0\\ 0&0&1&0&-1&0&0&0\\ 0&0&0&0&1&0&-1&0\end{bmatrix},

with :math:`M_i = 1` for :math:`i = \Theta(k)` and 0 otherwise (Table 1), and
:math:`R(\Theta) = \mathrm{diag}(\sigma^2_{a,\Theta}, \sigma^2_{e_h}, \sigma^2_{e_k}, \sigma^2_{e_a})` (eq. 27).
The Markov state and its reliability index are (eqs. 28–30, with the absolute value of seed 000 eq. 28)

.. math:: \rho(k) = \min_i \big|\|a_i\| - g\big|,\qquad \Theta(k) = \arg\min_i \big|\|a_i\| - g\big|,

and the filter corrects only when :math:`\rho(k)\le\zeta`; otherwise it only predicts (seed 002 §3).
``encoder_rows="always"`` is an option that keeps the encoder rows at every sample (our extension).
Discretisation, noise and the update are those of :mod:`estimators.markov.core` (eqs. 19–25).

Standard KF and the collaborative KF (seed 002 §4; seed 000 Appendix A)
-----------------------------------------------------------------------
The *standard* (local) filter is one FKC per segment: segment :math:`i` is corrected by its own
accelerometer whenever :math:`|\|a_i\|-g|\le\zeta` (Algorithm 3 with the encoder rows removed); its
:math:`H` is block-diagonal, so no segment helps another (A.1.1).  The *collaborative* (global) filter
(A.1.2, Algorithm 3) uses every reliable accelerometer together with the encoder rows :math:`[r, -r]`,
which couple the segments through the cross terms of :math:`K`.

Parameters (Table 2)
--------------------
The seed's Table 2 lists GA-optimised weights per segment without units.  We read them as the
diagonal entries (variances) of :math:`Q` and :math:`R` in degree units — :math:`q_\theta` (deg²/s),
:math:`q_b` (deg²/s³), :math:`\sigma_a^2` (deg²) — so that the accelerometer angle's standard
deviation is 7–18°, plausible in gait; :math:`\tau_g` in s; :math:`\zeta = 0.01` in units of
:math:`g`.  The encoder variance is not given in seed 002; we take 0.5 deg² from seed 000 Table 5.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from estimators.markov.core import FilterState, FloatArray, initial_state, run_filter, run_filter_reference
from estimators.markov.fkc import GRAVITY_M_S2

__all__ = ["MjlsParams", "MjlsResult", "markov_state", "mkf", "standard_kf", "collaborative_kf", "SEGMENTS"]

SEGMENTS = ("B", "T", "S", "F")
DEG2 = (np.pi / 180.0) ** 2


def _tuple(value, name: str, n: int | None = None, positive: bool = True) -> tuple[float, ...]:
    v = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if v.ndim != 1 or (n is not None and v.size != n):
        raise ValueError(f"{name} must be a sequence of {n} numbers, got {value!r}")
    if not np.all(np.isfinite(v)) or (np.any(v <= 0) if positive else np.any(v < 0)):
        raise ValueError(f"{name} must hold finite numbers {'> 0' if positive else '>= 0'}, got {value!r}")
    return tuple(float(x) for x in v)


@dataclass(frozen=True)
class MjlsParams:
    """Per-segment parameters (sequences of one value per segment, default four: B, T, S, F).

    q_angle_deg2_s : angle process-noise density :math:`\\sigma_g^2`, deg²/s (Table 2: 0.0103, 0.0017, 0.0008, 7.7482).
    q_bias_deg2_s3 : bias process-noise density :math:`\\sigma_{b_g}^2`, deg²/s³ (0.0003, 0.0005, 9.6405, 18.594).
    r_acc_deg2 : accelerometer-angle variance :math:`\\sigma_a^2`, deg² (46.562, 329.08, 100.94, 291.29).
    tau_gyro_s : bias correlation time :math:`\\tau_g`, s (839.70, 2138.5, 1465.3, 3567.5).
    zeta_g : reliability threshold ζ on :math:`|\\|a\\|-g|`, in units of g (0.01).
    r_enc_deg2 : encoder variance per joint, deg² (0.5, seed 000 Table 5), one value or one per joint.
    encoder_rows : ``"with_accelerometer"`` (seed: rows only at corrected samples) or ``"always"``.
    gravity_m_s2 : g (9.81).   p0_angle_deg2, p0_bias_deg2_s2 : initial covariance (1.0, 1.0).
    """

    q_angle_deg2_s: tuple = (0.0103, 0.0017, 0.0008, 7.7482)
    q_bias_deg2_s3: tuple = (0.0003, 0.0005, 9.6405, 18.594)
    r_acc_deg2: tuple = (46.562, 329.08, 100.94, 291.29)
    tau_gyro_s: tuple = (839.70, 2138.5, 1465.3, 3567.5)
    zeta_g: float = 0.01
    r_enc_deg2: tuple = (0.5,)
    encoder_rows: str = "with_accelerometer"
    gravity_m_s2: float = GRAVITY_M_S2
    p0_angle_deg2: float = 1.0
    p0_bias_deg2_s2: float = 1.0

    def __post_init__(self) -> None:
        n = len(np.atleast_1d(self.q_angle_deg2_s))
        object.__setattr__(self, "q_angle_deg2_s", _tuple(self.q_angle_deg2_s, "q_angle_deg2_s", n, False))
        object.__setattr__(self, "q_bias_deg2_s3", _tuple(self.q_bias_deg2_s3, "q_bias_deg2_s3", n, False))
        object.__setattr__(self, "r_acc_deg2", _tuple(self.r_acc_deg2, "r_acc_deg2", n))
        object.__setattr__(self, "tau_gyro_s", _tuple(self.tau_gyro_s, "tau_gyro_s", n))
        object.__setattr__(self, "r_enc_deg2", _tuple(self.r_enc_deg2, "r_enc_deg2"))
        if len(self.r_enc_deg2) not in (1, n - 1) and n > 1:
            raise ValueError(f"r_enc_deg2 must hold 1 or {n - 1} values (one per joint), got {self.r_enc_deg2!r}")
        if np.isnan(self.zeta_g) or self.zeta_g < 0:
            raise ValueError(f"zeta_g must be >= 0 (inf: always correct), got {self.zeta_g!r}")
        if self.encoder_rows not in ("with_accelerometer", "always"):
            raise ValueError(f"encoder_rows must be 'with_accelerometer' or 'always', got {self.encoder_rows!r}")
        if not (np.isfinite(self.gravity_m_s2) and self.gravity_m_s2 > 0):
            raise ValueError(f"gravity_m_s2 must be > 0, got {self.gravity_m_s2!r}")

    @property
    def n_segments(self) -> int:
        return len(self.q_angle_deg2_s)

    def scaled(self, factors: dict[str, ArrayLike]) -> MjlsParams:
        """A copy with the named per-segment fields multiplied by ``factors[name]`` (uncertainty studies)."""
        kw = {k: tuple(np.asarray(getattr(self, k)) * np.asarray(v)) for k, v in factors.items()}
        return MjlsParams(**{**self.__dict__, **kw})


@dataclass
class MjlsResult:
    """theta_rad : (N, n) absolute angles.   joint_rad : (N, n−1) relative angles θ_{i} − θ_{i+1}.
    gyro_bias_rad_s : (N, n).   markov_state : (N,) Θ(k) index (0 = first segment).
    corrected : (N,) bool, ρ(k) ≤ ζ.   rho_m_s2 : (N,) ρ(k).   state : final :class:`FilterState`.
    gains : per-sample Kalman gains (reference run with ``keep_gains``), else None."""

    theta_rad: FloatArray
    joint_rad: FloatArray
    gyro_bias_rad_s: FloatArray
    markov_state: FloatArray
    corrected: FloatArray
    rho_m_s2: FloatArray
    state: FilterState
    gains: list | None = field(default=None, repr=False)


def markov_state(acc_norm_m_s2: ArrayLike, gravity_m_s2: float, zeta_m_s2: float) -> tuple:
    """Eqs. 28–30: ``(Θ(k) (N,) int, ρ(k) (N,), reliable (N,) bool)`` from accelerometer norms (N, n)."""
    d = np.abs(np.asarray(acc_norm_m_s2, dtype=np.float64) - gravity_m_s2)
    d = np.where(np.isfinite(d), d, np.inf)
    state = np.argmin(d, axis=1)
    rho = d[np.arange(len(d)), state]
    return state, rho, rho <= zeta_m_s2


def _prepare(omega_rad_s, theta_acc_rad, acc_norm_m_s2, encoder_rad, params):
    w = np.asarray(omega_rad_s, dtype=np.float64)
    n = params.n_segments
    if w.ndim != 2 or w.shape[1] != n:
        raise ValueError(f"omega_rad_s must have shape (N, {n}) (one column per segment), got {w.shape}")
    za = np.asarray(theta_acc_rad, dtype=np.float64)
    an = np.asarray(acc_norm_m_s2, dtype=np.float64)
    for name, v in (("theta_acc_rad", za), ("acc_norm_m_s2", an)):
        if v.shape != w.shape:
            raise ValueError(f"{name} must have shape {w.shape}, got {v.shape}")
    if encoder_rad is None:
        enc = np.full((len(w), n - 1), np.nan)
    else:
        enc = np.asarray(encoder_rad, dtype=np.float64).reshape(len(w), -1)
        if enc.shape != (len(w), n - 1):
            raise ValueError(f"encoder_rad must have shape {(len(w), n - 1)} (NaN where no sample), got {enc.shape}")
    return w, za, an, enc


def _run(w, za, use_abs, enc, use_enc, params, fs_hz, theta0, state, reference, keep_gains):
    n = params.n_segments
    if not (np.isfinite(fs_hz) and fs_hz > 0):
        raise ValueError(f"fs_hz must be a positive number, got {fs_hz!r}")
    if state is None:
        th0 = np.where(np.isfinite(za[0]), za[0], 0.0) if theta0 is None else np.asarray(theta0, float)
        state = initial_state(th0, params.p0_angle_deg2 * DEG2, params.p0_bias_deg2_s2 * DEG2)
    pairs = np.array([[i, i + 1] for i in range(n - 1)], dtype=np.int64).reshape(-1, 2)
    r_enc = np.broadcast_to(np.asarray(params.r_enc_deg2) * DEG2, (n - 1,))
    kw = dict(dt_s=1.0 / fs_hz, tau_s=np.array(params.tau_gyro_s),
              q_angle_rad2_s=np.array(params.q_angle_deg2_s) * DEG2,
              q_bias_rad2_s3=np.array(params.q_bias_deg2_s3) * DEG2, state=state)
    args = (w, np.where(use_abs, za, 0.0), np.array(params.r_acc_deg2) * DEG2, use_abs, np.where(use_enc, enc, 0.0),
            pairs, r_enc, use_enc)
    if reference:
        out = run_filter_reference(*args, keep_gains=keep_gains, **kw)
        return out if keep_gains else out + (None,)
    return run_filter(*args, **kw) + (None,)


def mkf(omega_rad_s: ArrayLike, theta_acc_rad: ArrayLike, acc_norm_m_s2: ArrayLike, encoder_rad: ArrayLike | None,
        *, fs_hz: float, params: MjlsParams | None = None, theta0_rad: ArrayLike | None = None,
        state: FilterState | None = None, fixed_state: int | None = None, reference: bool = False,
        keep_gains: bool = False) -> MjlsResult:
    """Markovian Kalman filter (eqs. 21–30).

    omega_rad_s, theta_acc_rad, acc_norm_m_s2 : (N, n) per-segment sagittal rate, accelerometer angle and
    accelerometer norm ‖a_i‖.  encoder_rad : (N, n−1) joint angles θ_i − θ_{i+1} (NaN where an encoder
    has no sample, e.g. 50 Hz encoders on a 100 Hz grid) or None.  ``fixed_state`` forces Θ(k) (tests).
    """
    params = MjlsParams() if params is None else params
    w, za, an, enc = _prepare(omega_rad_s, theta_acc_rad, acc_norm_m_s2, encoder_rad, params)
    theta_state, rho, ok = markov_state(an, params.gravity_m_s2, params.zeta_g * params.gravity_m_s2)
    if fixed_state is not None:
        theta_state = np.full(len(w), int(fixed_state))
        rho = np.abs(an[:, int(fixed_state)] - params.gravity_m_s2)
        ok = rho <= params.zeta_g * params.gravity_m_s2
    use_abs = np.zeros(w.shape, dtype=bool)
    use_abs[np.arange(len(w)), theta_state] = ok
    use_abs &= np.isfinite(za)
    use_enc = np.isfinite(enc)
    if params.encoder_rows == "with_accelerometer":
        use_enc &= ok[:, None]
    th, bias, st, gains = _run(w, za, use_abs, enc, use_enc, params, fs_hz, theta0_rad, state, reference, keep_gains)
    return MjlsResult(th, th[:, :-1] - th[:, 1:], bias, theta_state, ok, rho, st, gains)


def standard_kf(omega_rad_s: ArrayLike, theta_acc_rad: ArrayLike, acc_norm_m_s2: ArrayLike, *, fs_hz: float,
                params: MjlsParams | None = None, theta0_rad: ArrayLike | None = None,
                reference: bool = False) -> MjlsResult:
    """Standard (local) KF: one FKC per segment, each corrected by its own reliable accelerometer (A.1.1)."""
    return _local_or_global(omega_rad_s, theta_acc_rad, acc_norm_m_s2, None, fs_hz, params, theta0_rad, reference,
                            False)


def collaborative_kf(omega_rad_s: ArrayLike, theta_acc_rad: ArrayLike, acc_norm_m_s2: ArrayLike,
                     encoder_rad: ArrayLike | None, *, fs_hz: float, params: MjlsParams | None = None,
                     theta0_rad: ArrayLike | None = None, reference: bool = False,
                     keep_gains: bool = False) -> MjlsResult:
    """Collaborative (global) KF: every reliable accelerometer plus the encoder rows (A.1.2, Algorithm 3)."""
    return _local_or_global(omega_rad_s, theta_acc_rad, acc_norm_m_s2, encoder_rad, fs_hz, params, theta0_rad,
                            reference, keep_gains)


def _local_or_global(omega, za, an, enc, fs_hz, params, theta0, reference, keep_gains=False):
    params = MjlsParams() if params is None else params
    w, za, an, encm = _prepare(omega, za, an, enc, params)
    d = np.abs(an - params.gravity_m_s2)
    use_abs = (d <= params.zeta_g * params.gravity_m_s2) & np.isfinite(za)
    use_enc = np.isfinite(encm)
    if params.encoder_rows == "with_accelerometer":
        use_enc &= use_abs.any(axis=1)[:, None]
    th, bias, st, gains = _run(w, za, use_abs, encm, use_enc, params, fs_hz, theta0, None, reference, keep_gains)
    best = np.argmin(np.where(np.isfinite(d), d, np.inf), axis=1)
    return MjlsResult(th, th[:, :-1] - th[:, 1:], bias, best, use_abs.any(axis=1), d[np.arange(len(d)), best], st,
                      gains)
