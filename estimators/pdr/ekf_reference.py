"""Readable numpy reference of :mod:`estimators.pdr.ekf` (dense F, H and K, eqs. 3.30–3.44), for tests.

Same maths, same order of operations as the compiled kernel; see :mod:`estimators.pdr.ekf` for the
equations and conventions.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from estimators.pdr.ekf import EkfOutput, EkfParams, FloatArray, _args
from estimators.pdr.mechanisation import GRAVITY_M_S2, cayley

__all__ = ["run_ekf_reference"]


def _skew(a: FloatArray) -> FloatArray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _reference(acc, gyr, dt_s, stance, c_ext, use_ext, ns, zaru, c0, bg0, ba0, p0_diag,
               q_gyr, q_acc, q_bg, q_ba, r_zupt, r_zaru, gravity,
               use_hdr, hdr_gate, hdr_straight, r_hdr, use_height, height_gate, r_height, att_var_body, use_att_var):
    n = len(acc)
    i3 = np.eye(3)
    p = np.diag(p0_diag).astype(np.float64)
    c, bg, ba = c0.copy(), bg0.copy(), ba0.copy()
    pos, vel = np.zeros(3), np.zeros(3)
    out = [np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, ns))]
    state = {"c": c, "pos": pos, "vel": vel, "bg": bg, "ba": ba}

    def update(h: FloatArray, z: FloatArray, r_var: float) -> None:
        nonlocal p
        k_gain = p @ h.T @ np.linalg.inv(h @ p @ h.T + r_var * np.eye(len(z)))   # (3.36)
        dx = k_gain @ z                                                            # (3.35)
        p = p - k_gain @ h @ p                                                     # (3.38)
        p = 0.5 * (p + p.T)
        state["pos"] = state["pos"] - dx[3:6]                                      # (3.39)
        state["vel"] = state["vel"] - dx[6:9]                                      # (3.40)
        if not use_ext:
            state["c"] = cayley(-dx[0:3]) @ state["c"]                            # (3.41)
        if ns == 15:
            state["bg"] = state["bg"] - dx[9:12]
            state["ba"] = state["ba"] - dx[12:15]

    def sel(start: int, m: int) -> FloatArray:
        h = np.zeros((m, ns))
        h[:, start:start + m] = np.eye(m)
        return h

    n_stances, psi_ref, psi_prev, z_floor = 0, 0.0, 0.0, 0.0
    xy_prev = np.zeros(2)
    wrap = lambda a: (a + np.pi) % (2.0 * np.pi) - np.pi  # noqa: E731
    for k in range(n):
        if use_ext:
            state["c"] = c_ext[k].copy()
        if k > 0:
            dt = dt_s[k]
            if not use_ext:
                state["c"] = state["c"] @ cayley((gyr[k] - state["bg"]) * dt)
            f_n = state["c"] @ (acc[k] - state["ba"])
            state["vel"] = state["vel"] + (f_n - np.array([0.0, 0.0, gravity])) * dt
            state["pos"] = state["pos"] + state["vel"] * dt
            f = np.eye(ns)                                                         # (3.31) / (3.44)
            f[3:6, 6:9] = i3 * dt
            f[6:9, 0:3] = -_skew(f_n) * dt
            if ns == 15:
                f[0:3, 9:12] = -state["c"] * dt
                f[6:9, 12:15] = -state["c"] * dt
            q = np.zeros(ns)
            q[0:3], q[6:9] = q_gyr * dt, q_acc * dt
            if ns == 15:
                q[9:12], q[12:15] = q_bg * dt, q_ba * dt
            p = f @ p @ f.T + np.diag(q)                                           # (3.37)
            if use_att_var:                                                        # clipped rates
                p[0:3, 0:3] += state["c"] @ np.diag(att_var_body[k]) @ state["c"].T
        if stance[k]:
            update(sel(6, 3), state["vel"].copy(), r_zupt)                         # ZUPT
            if zaru:
                update(sel(9, 3), state["bg"] - gyr[k], r_zaru)                    # ZARU
            if k == n - 1 or not stance[k + 1]:
                n_stances += 1
                if use_hdr and not use_ext and n_stances >= 2:
                    d = state["pos"][:2] - xy_prev
                    psi = np.arctan2(d[1], d[0])                                   # stride direction
                    if n_stances == 2:
                        psi_ref = psi
                    elif abs(wrap(psi - psi_prev)) < hdr_straight:
                        m = np.floor(wrap(psi - psi_ref) / (np.pi / 2) + 0.5)
                        e = wrap(psi - (psi_ref + m * np.pi / 2))
                        if abs(e) < hdr_gate:
                            update(sel(2, 1), np.array([e]), r_hdr)
                    psi_prev = psi
                xy_prev = state["pos"][:2].copy()
                if use_height:
                    if n_stances == 1:
                        z_floor = state["pos"][2]
                    elif abs(state["pos"][2] - z_floor) < height_gate:
                        update(sel(5, 1), np.array([state["pos"][2] - z_floor]), r_height)
                    else:
                        z_floor = state["pos"][2]
        for arr, val in zip(out, (state["pos"], state["vel"], state["c"], state["bg"], state["ba"], np.diag(p))):
            arr[k] = val
    return tuple(out)


def run_ekf_reference(acc: ArrayLike, gyr: ArrayLike, dt_s: ArrayLike, stance: ArrayLike, c0: ArrayLike,
                      gyr_bias0_rad_s: ArrayLike, params: EkfParams = EkfParams(), *,
                      c_ext: ArrayLike | None = None, gravity_m_s2: float = GRAVITY_M_S2,
                      att_var_body: ArrayLike | None = None) -> EkfOutput:
    """Readable dense-matrix numpy version of :func:`run_ekf` (same maths; for tests)."""
    return EkfOutput(*_reference(*_args(acc, gyr, dt_s, stance, c0, gyr_bias0_rad_s, params, c_ext, gravity_m_s2,
                                        att_var_body)))
