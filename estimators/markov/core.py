r"""Switched error-state complementary Kalman filter: the engine of FKC, MJLS, SMe and SMeA.

Every filter of this package (seed 000 §2.1.4–§2.4, seed 002 §2–3) is the same linear Kalman
filter on the *errors* of gyroscope-integrated angles; only the choice of measurement rows changes
from sample to sample.  This module holds that filter once: a numba kernel and a readable numpy
reference with the same maths.

Model (seed 000 eqs. 7–24; seed 002 eqs. 1–13)
-----------------------------------------------
For each angle channel :math:`i = 1..m` (one axis of one segment) the gyroscope angle is the
integral of the measured rate (eq. 7), discretised as
:math:`\theta_{g,i}[k] = \theta_{g,i}[k-1] + T\,\omega_i[k]`, and the error state is
:math:`x_i = [\Delta\theta_i,\ \Delta b_i]` with :math:`\Delta\theta_i = \theta_i - \theta_{g,i}` and
:math:`\Delta b_i` the (negated) gyroscope bias error, a first-order Gauss–Markov process (eq. 19)

.. math:: \dot x_i = A_i x_i + w_i,\qquad A_i = \begin{bmatrix}0 & 1\\ 0 & -1/\tau_{g,i}\end{bmatrix}.

Discretisation (eq. 21): :math:`F = I + A T`.  The seeds write :math:`G = A^{-1}(F-I)\bar B`; :math:`A`
is singular (its first column is zero) but :math:`F - I = AT`, so the product is :math:`G = T\,I`
exactly.  To keep the parameters independent of the sampling rate (house rule) the process noise is
given as continuous power spectral densities :math:`q_\theta` (rad²/s, the gyroscope's angle random
walk density squared) and :math:`q_b` (rad²/s³, the bias random-walk density squared), and the
discrete covariance is :math:`Q_d = G Q G^T = T\,\mathrm{diag}(q_\theta, q_b)`, i.e. the seeds'
:math:`Q` (eq. 23) read as :math:`\mathrm{diag}(q_\theta, q_b)/T`.

Measurements (eqs. 9, 20; seed 002 eqs. 17–18):

* absolute row of channel :math:`i`: :math:`z = \theta_{a,i} - \theta_{g,i} = \Delta\theta_i + \eta_a`,
  :math:`H` = 1 at :math:`\Delta\theta_i` (the selection matrices :math:`M_i`, seed 002 Table 1,
  seed 000 Tables 1–4 choose which of these rows exist at sample :math:`k`);
* relative row :math:`(a, b)` (encoder or self-aligned joint angle :math:`\alpha = \theta_a - \theta_b`):
  :math:`z = \alpha - (\theta_{g,a} - \theta_{g,b}) = \Delta\theta_a - \Delta\theta_b + \eta_e`,
  :math:`H` = +1, −1 at :math:`\Delta\theta_a, \Delta\theta_b` (the rows ``[r, -r]`` of eq. 30).

Kalman filter (Algorithm 1/2, seed 002 eqs. 21–25): predict :math:`\hat x = F\hat x`,
:math:`P = FPF^T + Q_d`; correct with the rows present at :math:`k`:
:math:`K = PH^T(HPH^T+R)^{-1}`, :math:`\hat x \mathrel{+}= K(z - H\hat x)`, :math:`P = (I-KH)P`; output
:math:`\hat\theta_i = \theta_{g,i} + \Delta\hat\theta_i` (eq. 10).  The sample with no row present is a
prediction only (seed 002 §3, "unreliable measurement signal").

Implementation: :math:`R` is diagonal, so the kernel processes the rows one at a time (sequential
scalar updates); this is algebraically identical to the batch update above (which the reference
computes literally) and needs no matrix inverse and no allocation per sample.  The prediction uses
the block structure of :math:`F` (:math:`O(n^2)` per sample).

Per-sample measurement variances are inputs, so a caller can make :math:`R` depend on the Markov
state (:math:`R(\Theta)`, seed 002 eq. 27; :math:`R(\Xi)`, seed 000 eqs. 82–84).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = ["FilterState", "run_filter", "run_filter_reference", "initial_state"]


@dataclass
class FilterState:
    """State of the switched error-state filter (everything needed to continue a stream).

    theta_g_rad : (m,) gyroscope-integrated angles at the last sample.
    x : (2m,) error state ``[Δθ_1, Δb_1, Δθ_2, Δb_2, ...]`` (rad, rad/s; Δb = −gyroscope bias).
    p : (2m, 2m) error covariance.
    """

    theta_g_rad: FloatArray
    x: FloatArray
    p: FloatArray

    def copy(self) -> FilterState:
        return FilterState(self.theta_g_rad.copy(), self.x.copy(), self.p.copy())


def initial_state(theta0_rad: FloatArray, p_angle_rad2: float = 0.0, p_bias_rad2_s2: float = 1e-4) -> FilterState:
    """Start state: ``θ_g = theta0_rad``, zero error, diagonal covariance (angle, bias variances)."""
    theta0 = np.asarray(theta0_rad, dtype=np.float64).reshape(-1).copy()
    m = theta0.size
    p = np.zeros((2 * m, 2 * m))
    for i in range(m):
        p[2 * i, 2 * i] = p_angle_rad2
        p[2 * i + 1, 2 * i + 1] = p_bias_rad2_s2
    return FilterState(theta0, np.zeros(2 * m), p)


@njit(cache=True)
def _mkf_batch(omega, z_abs, r_abs, use_abs, z_rel, rel_a, rel_b, r_rel, use_rel,
               dt_s, tau_s, q_angle, q_bias, theta_g0, x0, p0):
    n_samples, m = omega.shape
    n_rel = rel_a.shape[0]
    n = 2 * m
    theta_g = theta_g0.copy()
    x = x0.copy()
    p = p0.copy()
    theta_out = np.empty((n_samples, m))
    bias_out = np.empty((n_samples, m))
    c = np.empty(n)
    decay = np.empty(m)
    for i in range(m):
        decay[i] = 1.0 - dt_s / tau_s[i]
    for k in range(n_samples):
        # prediction (eqs. 21-22): rows then columns of F P F^T, F = I + A T
        for i in range(m):
            theta_g[i] += dt_s * omega[k, i]
            x[2 * i] += dt_s * x[2 * i + 1]
            x[2 * i + 1] *= decay[i]
        for i in range(m):
            a = 2 * i
            b = a + 1
            for j in range(n):
                p[a, j] += dt_s * p[b, j]
                p[b, j] *= decay[i]
        for i in range(m):
            a = 2 * i
            b = a + 1
            for j in range(n):
                p[j, a] += dt_s * p[j, b]
                p[j, b] *= decay[i]
        for i in range(m):
            p[2 * i, 2 * i] += dt_s * q_angle[i]
            p[2 * i + 1, 2 * i + 1] += dt_s * q_bias[i]
        # correction (eqs. 23-25), one scalar row at a time
        for i in range(m):
            if not use_abs[k, i]:
                continue
            a = 2 * i
            innov = z_abs[k, i] - theta_g[i] - x[a]
            for j in range(n):
                c[j] = p[j, a]
            s = c[a] + r_abs[k, i]
            for j in range(n):
                x[j] += c[j] / s * innov
            for j in range(n):
                kj = c[j] / s
                for l in range(n):
                    p[j, l] -= kj * c[l]
        for r in range(n_rel):
            if not use_rel[k, r]:
                continue
            a = 2 * rel_a[r]
            b = 2 * rel_b[r]
            innov = z_rel[k, r] - (theta_g[rel_a[r]] - theta_g[rel_b[r]]) - (x[a] - x[b])
            for j in range(n):
                c[j] = p[j, a] - p[j, b]
            s = c[a] - c[b] + r_rel[k, r]
            for j in range(n):
                x[j] += c[j] / s * innov
            for j in range(n):
                kj = c[j] / s
                for l in range(n):
                    p[j, l] -= kj * c[l]
        for i in range(m):
            theta_out[k, i] = theta_g[i] + x[2 * i]
            bias_out[k, i] = -x[2 * i + 1]
    return theta_out, bias_out, theta_g, x, p


def _check(omega, z_abs, r_abs, use_abs, z_rel, rel_pairs, r_rel, use_rel, state):
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    if omega.ndim != 2:
        raise ValueError(f"omega_rad_s must have shape (N, m), got {omega.shape}")
    n, m = omega.shape
    z_abs = np.ascontiguousarray(z_abs, dtype=np.float64)
    r_abs = np.ascontiguousarray(np.broadcast_to(np.asarray(r_abs, dtype=np.float64), (n, m)))
    use_abs = np.ascontiguousarray(np.broadcast_to(np.asarray(use_abs, dtype=np.bool_), (n, m)))
    if z_abs.shape != (n, m):
        raise ValueError(f"theta_abs_rad must have shape {(n, m)}, got {z_abs.shape}")
    pairs = np.asarray(rel_pairs, dtype=np.int64).reshape(-1, 2)
    p_rel = len(pairs)
    z_rel = np.ascontiguousarray(np.asarray(z_rel, dtype=np.float64).reshape(n, p_rel))
    r_rel = np.ascontiguousarray(np.broadcast_to(np.asarray(r_rel, dtype=np.float64), (n, p_rel)))
    use_rel = np.ascontiguousarray(np.broadcast_to(np.asarray(use_rel, dtype=np.bool_), (n, p_rel)))
    if p_rel and (pairs.min() < 0 or pairs.max() >= m):
        raise ValueError(f"relative row pairs must index channels 0..{m - 1}, got {pairs.tolist()}")
    used_r = np.concatenate([r_abs[use_abs], r_rel[use_rel]])
    if used_r.size and not np.all(used_r > 0.0):
        raise ValueError("measurement variances must be > 0 where a row is used")
    if state.theta_g_rad.shape != (m,) or state.x.shape != (2 * m,) or state.p.shape != (2 * m, 2 * m):
        raise ValueError(f"state does not match {m} channels")
    return omega, z_abs, r_abs, use_abs, z_rel, np.ascontiguousarray(pairs[:, 0]), \
        np.ascontiguousarray(pairs[:, 1]), r_rel, use_rel


def run_filter(omega_rad_s, theta_abs_rad, r_abs_rad2, use_abs, theta_rel_rad, rel_pairs, r_rel_rad2, use_rel, *,
               dt_s: float, tau_s, q_angle_rad2_s, q_bias_rad2_s3, state: FilterState):
    """Run the numba kernel.

    omega_rad_s : (N, m) rates about each channel's axis.  theta_abs_rad : (N, m) absolute angle
    measurements (accelerometer angles); r_abs_rad2 : their variances (N, m) or broadcastable;
    use_abs : (N, m) bool, the rows present at each sample.  theta_rel_rad : (N, p) relative angles,
    rel_pairs : (p, 2) channel pairs ``(a, b)`` with ``α = θ_a − θ_b``; r_rel_rad2, use_rel likewise.
    tau_s, q_angle_rad2_s, q_bias_rad2_s3 : (m,) model parameters.  ``state`` is not modified.

    Returns ``(theta_rad (N, m), gyro_bias_rad_s (N, m), new FilterState)``.
    """
    args = _check(omega_rad_s, theta_abs_rad, r_abs_rad2, use_abs, theta_rel_rad, rel_pairs, r_rel_rad2, use_rel,
                  state)
    m = args[0].shape[1]
    par = [np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=np.float64), (m,))) for v in
           (tau_s, q_angle_rad2_s, q_bias_rad2_s3)]
    th, bias, tg, x, p = _mkf_batch(*args, float(dt_s), par[0], par[1], par[2], state.theta_g_rad.astype(np.float64),
                                    state.x.astype(np.float64), state.p.astype(np.float64))
    return th, bias, FilterState(tg, x, p)


def run_filter_reference(omega_rad_s, theta_abs_rad, r_abs_rad2, use_abs, theta_rel_rad, rel_pairs, r_rel_rad2,
                         use_rel, *, dt_s: float, tau_s, q_angle_rad2_s, q_bias_rad2_s3, state: FilterState,
                         keep_gains: bool = False):
    """Readable numpy version of :func:`run_filter` (batch update, eqs. 21–25 written literally).

    With ``keep_gains`` it also returns, per sample, the gain ``K`` (2m, rows) and the row labels
    (``("abs", i)`` or ``("rel", r)``) as a list of ``(K, labels)`` (``None`` where nothing was used).
    """
    omega, z_abs, r_abs, use_abs, z_rel, rel_a, rel_b, r_rel, use_rel = _check(
        omega_rad_s, theta_abs_rad, r_abs_rad2, use_abs, theta_rel_rad, rel_pairs, r_rel_rad2, use_rel, state)
    n_s, m = omega.shape
    n = 2 * m
    tau = np.broadcast_to(np.asarray(tau_s, dtype=np.float64), (m,))
    a_bar = np.zeros((n, n))
    for i in range(m):
        a_bar[2 * i, 2 * i + 1] = 1.0
        a_bar[2 * i + 1, 2 * i + 1] = -1.0 / tau[i]
    f = np.eye(n) + a_bar * dt_s                                    # F = I + A T (eq. 21)
    g = dt_s * np.eye(n)                                            # G = A^-1 (F - I) B = T I
    q = np.diag(np.ravel(np.column_stack([np.broadcast_to(q_angle_rad2_s, (m,)),
                                          np.broadcast_to(q_bias_rad2_s3, (m,))]))) / dt_s
    theta_g = state.theta_g_rad.astype(np.float64).copy()
    x = state.x.astype(np.float64).copy()
    p = state.p.astype(np.float64).copy()
    theta_out = np.empty((n_s, m))
    bias_out = np.empty((n_s, m))
    gains = []
    for k in range(n_s):
        theta_g = theta_g + dt_s * omega[k]                         # eq. 7
        x = f @ x                                                   # eq. 21
        p = f @ p @ f.T + g @ q @ g.T                               # eq. 22
        rows, z, r, labels = [], [], [], []
        for i in range(m):
            if use_abs[k, i]:
                h = np.zeros(n)
                h[2 * i] = 1.0
                rows.append(h)
                z.append(z_abs[k, i] - theta_g[i])                  # eq. 9
                r.append(r_abs[k, i])
                labels.append(("abs", i))
        for j in range(len(rel_a)):
            if use_rel[k, j]:
                h = np.zeros(n)
                h[2 * rel_a[j]] = 1.0
                h[2 * rel_b[j]] = -1.0
                rows.append(h)
                z.append(z_rel[k, j] - (theta_g[rel_a[j]] - theta_g[rel_b[j]]))
                r.append(r_rel[k, j])
                labels.append(("rel", j))
        if rows:
            hm = np.array(rows)
            kg = p @ hm.T @ np.linalg.inv(hm @ p @ hm.T + np.diag(r))  # eq. 23
            x = x + kg @ (np.array(z) - hm @ x)                     # eq. 24
            p = (np.eye(n) - kg @ hm) @ p                           # eq. 25
            p = 0.5 * (p + p.T)
            if keep_gains:
                gains.append((kg, labels))
        elif keep_gains:
            gains.append(None)
        theta_out[k] = theta_g + x[0::2]                            # eq. 10
        bias_out[k] = -x[1::2]
    out = (theta_out, bias_out, FilterState(theta_g, x, p))
    return out + (gains,) if keep_gains else out
