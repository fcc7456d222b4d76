"""Procedural femur and tibia meshes, and a still of the knee at three key poses.

Meshes
------
Both bones are generated here from a handful of closed primitives (no third-party meshes): a *loft*
(rings of ellipses along a local axis, each end closed by a cap vertex) and ellipsoids (a loft whose end
rings shrink to a pole).  Every primitive is a closed, consistently wound surface with outward normals
(right-hand rule: ``(v1 - v0) × (v2 - v0)`` points out of the bone); primitives overlap where bones have
bumps, so the bone is a union of watertight components (what a renderer needs; no CSG).

Frames and anchors (ISB segment frames: x anterior, y proximal along the long axis, z to the right;
metres; drawn for the **right** leg, the left one is the mirror image ``z → −z`` with the face winding
flipped, :func:`mirror`):

* femur: origin at the knee joint centre (between the condyles), the y axis is the *mechanical* axis,
  so the hip joint centre (centre of the femoral head) is at ``(0, L_femur, 0)``.  The shaft therefore
  leans laterally (+z) by the anatomical-mechanical angle (~6°) and the neck goes medially to the head.
  Parts: two condyles, distal metaphysis, shaft (slight anterior bow), greater and lesser trochanters,
  neck, head.
* tibia: origin at the ankle joint centre (between the malleoli); the knee joint centre is at
  ``(0, L_tibia, 0)``.  Parts: shaft, the plateau's two condyles, tibial tuberosity, medial malleolus,
  and the fibula (shaft, head, lateral malleolus).

Default lengths 0.42 m (femur) and 0.40 m (tibia); with a patient height H they scale to
0.245·H and 0.246·H (segment-length ratios of Winter's anthropometric table); the shape scales uniformly.

Key poses still
---------------
:func:`key_poses` computes the bones as shaded 2D triangles (orthographic lateral view; the PDF draws
them as vectors) at three instants of the first accepted
cycle: its onset (start posture), peak flexion (``countermovement_peak``) and full extension (``far_reached``, else ``far_left``), with the tibia
anchored at the ankle and the femur attached at the knee::

    p_ankle = 0,   p_knee = p_ankle + R_earth_tibia · [0, L_tibia, 0]

Each pose's heading (the azimuth of the tibia's anterior axis) is removed so the leg is seen from the
side.  Nothing clinical is computed: the instants come from ``results["cycles"]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimators import quaternion as quat

from .model import ReportInput

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: default segment lengths, m (knee→hip centre; ankle→knee centre)
FEMUR_LENGTH_M = 0.42
TIBIA_LENGTH_M = 0.40
#: segment length / body height (Winter, Biomechanics and Motor Control of Human Movement, Table 4.1)
FEMUR_HEIGHT_RATIO = 0.245
TIBIA_HEIGHT_RATIO = 0.246
#: bone colour (RGB 0..255), used by the still and the 3D scene
BONE_RGB = (227, 218, 201)


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh.  vertices (V, 3) float64 in metres; faces (F, 3) int64 indices, counter-clockwise
    seen from outside (outward normals)."""

    vertices: FloatArray
    faces: IntArray

    def normals(self) -> FloatArray:
        """(F, 3) unit face normals (outward)."""
        v = self.vertices[self.faces]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


# ---------------------------------------------------------------- primitives


def _loft(y: FloatArray, cx: FloatArray, cz: FloatArray, rx: FloatArray, rz: FloatArray,
          cap_low: float, cap_high: float, n_theta: int) -> tuple[FloatArray, IntArray]:
    """Closed tube along local y: ring k is the ellipse centred (cx[k], y[k], cz[k]) with semi-axes rx[k]
    (x) and rz[k] (z); the ends are closed by fans to cap vertices at y[0] - cap_low and y[-1] + cap_high
    (on the ring's centre line).  Returns (V, 3) vertices and outward-wound (F, 3) faces."""
    n_rings = len(y)
    theta = np.linspace(0.0, 2.0 * np.pi, n_theta, endpoint=False)
    ring = np.empty((n_rings, n_theta, 3))
    ring[:, :, 0] = cx[:, None] + rx[:, None] * np.cos(theta)
    ring[:, :, 1] = y[:, None]
    ring[:, :, 2] = cz[:, None] + rz[:, None] * np.sin(theta)
    low = np.array([[cx[0], y[0] - cap_low, cz[0]]])
    high = np.array([[cx[-1], y[-1] + cap_high, cz[-1]]])
    vertices = np.concatenate([ring.reshape(-1, 3), low, high])
    i_low, i_high = n_rings * n_theta, n_rings * n_theta + 1

    k, j = np.meshgrid(np.arange(n_rings - 1), np.arange(n_theta), indexing="ij")
    a = (k * n_theta + j).ravel()
    b = (k * n_theta + (j + 1) % n_theta).ravel()
    c = b + n_theta
    d = a + n_theta
    # theta runs x→z, i.e. clockwise seen from +y: (a, c, b) and (a, d, c) face outwards
    side = np.concatenate([np.stack([a, c, b], axis=1), np.stack([a, d, c], axis=1)])
    j = np.arange(n_theta)
    jn = (j + 1) % n_theta
    top0 = (n_rings - 1) * n_theta
    cap_l = np.stack([np.full(n_theta, i_low), j, jn], axis=1)
    cap_h = np.stack([np.full(n_theta, i_high), top0 + jn, top0 + j], axis=1)
    return vertices, np.concatenate([side, cap_l, cap_h]).astype(np.int64)


def _ellipsoid(center: Sequence[float], radii: Sequence[float], n_theta: int,
               rotation: FloatArray | None = None) -> tuple[FloatArray, IntArray]:
    """Closed ellipsoid with semi-axes radii (x, y, z) about its local axes, rotated then translated."""
    n_rings = max(4, n_theta // 2)
    phi = np.linspace(0.0, np.pi, n_rings + 2)[1:-1]          # polar angle from −y to +y, poles excluded
    rx, ry, rz = radii
    y = -ry * np.cos(phi)
    s = np.sin(phi)
    zeros = np.zeros_like(y)
    v, f = _loft(y, zeros, zeros, rx * s, rz * s, ry + y[0], ry - y[-1], n_theta)
    if rotation is not None:
        v = v @ np.asarray(rotation).T
    return v + np.asarray(center, dtype=float), f


def _tube(p0: Sequence[float], p1: Sequence[float], r0: float, r1: float, n_theta: int,
          n_rings: int = 6) -> tuple[FloatArray, IntArray]:
    """Closed (flat-capped) tapered tube from point p0 to point p1."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    t = np.linspace(0.0, 1.0, n_rings)
    zeros = np.zeros(n_rings)
    r = r0 + (r1 - r0) * t
    v, f = _loft(t * length, zeros, zeros, r, r, 0.0, 0.0, n_theta)
    rot = quat.to_matrix(quat.from_two_vectors(np.array([0.0, 1.0, 0.0]), axis / length))
    return v @ rot.T + p0, f


def _join(parts: Sequence[tuple[FloatArray, IntArray]]) -> Mesh:
    vertices, faces, offset = [], [], 0
    for v, f in parts:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return Mesh(np.concatenate(vertices), np.concatenate(faces))


def _smooth(t: FloatArray) -> FloatArray:
    """Smoothstep 0→1 on t in [0, 1] (clipped)."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# ---------------------------------------------------------------- bones (right leg, unit design length)


def _check_bone_args(length_m: float, n_theta: int) -> None:
    if not length_m > 0:
        raise ValueError(f"length_m must be > 0 (the bone length in metres), got {length_m}")
    if n_theta < 6:
        raise ValueError(f"n_theta must be >= 6 (points around each cross-section), got {n_theta}")


def femur_mesh(length_m: float = FEMUR_LENGTH_M, *, n_theta: int = 24) -> Mesh:
    """Right femur in its ISB frame, origin at the knee joint centre, hip centre at (0, length_m, 0)."""
    _check_bone_args(length_m, n_theta)
    s = length_m / FEMUR_LENGTH_M
    L = FEMUR_LENGTH_M
    parts = []
    # shaft: from the distal metaphysis (wide) to below the trochanters, leaning laterally
    y = np.linspace(0.012, L - 0.055, 3 * n_theta // 2 + 8)
    u = (y - y[0]) / (y[-1] - y[0])
    distal = 1.0 - _smooth((y - 0.012) / 0.11)                # 1 at the condyles, 0 on the shaft
    proximal = _smooth((y - (L - 0.12)) / 0.065)               # 1 at the intertrochanteric region
    cz = 0.047 * u ** 1.2                                      # ~6° anatomical-mechanical angle
    cx = 0.010 * np.sin(np.pi * u) - 0.004 * distal            # anterior bow
    rx = 0.0135 + 0.016 * distal + 0.006 * proximal
    rz = 0.0130 + 0.027 * distal + 0.010 * proximal
    parts.append(_loft(y, cx, cz, rx, rz, 0.004, 0.012, n_theta))
    # condyles (medial −z, lateral +z), long antero-posteriorly, reaching slightly below the joint centre
    for z_c in (-0.022, 0.023):
        parts.append(_ellipsoid((-0.006, 0.021, z_c), (0.031, 0.025, 0.0145), n_theta))
    # greater trochanter (lateral, postero-superior), lesser trochanter (postero-medial)
    parts.append(_ellipsoid((-0.006, L - 0.028, 0.061), (0.019, 0.033, 0.014), n_theta))
    parts.append(_ellipsoid((-0.014, L - 0.088, 0.030), (0.011, 0.014, 0.010), max(8, n_theta // 2)))
    # neck from the top of the shaft to the head, then the head centred on the hip joint centre
    parts.append(_tube((-0.004, L - 0.062, 0.046), (0.0, L, 0.0), 0.017, 0.014, n_theta))
    parts.append(_ellipsoid((0.0, L, 0.0), (0.0235, 0.0235, 0.0235), n_theta))
    mesh = _join(parts)
    return Mesh(mesh.vertices * s, mesh.faces)


def tibia_mesh(length_m: float = TIBIA_LENGTH_M, *, n_theta: int = 24, fibula: bool = True) -> Mesh:
    """Right tibia (and fibula) in the tibia's ISB frame, origin at the ankle joint centre, knee joint
    centre at (0, length_m, 0)."""
    _check_bone_args(length_m, n_theta)
    s = length_m / TIBIA_LENGTH_M
    L = TIBIA_LENGTH_M
    parts = []
    y = np.linspace(0.010, L - 0.022, 3 * n_theta // 2 + 8)
    distal = 1.0 - _smooth((y - 0.010) / 0.08)
    proximal = _smooth((y - (L - 0.13)) / 0.10)
    cx = 0.002 - 0.004 * proximal
    cz = -0.004 + 0.002 * proximal
    rx = 0.0130 + 0.008 * distal + 0.017 * proximal
    rz = 0.0120 + 0.012 * distal + 0.026 * proximal
    parts.append(_loft(y, cx, cz, rx, rz, 0.004, 0.004, n_theta))
    # plateau: medial and lateral condyles, flattened, their top just below the knee joint centre
    for z_c in (-0.020, 0.020):
        parts.append(_ellipsoid((-0.004, L - 0.018, z_c), (0.027, 0.011, 0.020), n_theta))
    # tibial tuberosity (anterior, below the plateau)
    parts.append(_ellipsoid((0.024, L - 0.062, 0.002), (0.009, 0.022, 0.012), max(8, n_theta // 2)))
    # medial malleolus (−z), reaching ~2 cm below the ankle joint centre
    parts.append(_ellipsoid((0.003, 0.004, -0.024), (0.012, 0.024, 0.008), n_theta))
    if fibula:
        parts.append(_tube((-0.010, 0.012, 0.027), (-0.014, L - 0.052, 0.036), 0.0075, 0.0085, n_theta // 2 + 2,
                           n_rings=8))
        parts.append(_ellipsoid((-0.014, L - 0.050, 0.037), (0.012, 0.013, 0.011), max(8, n_theta // 2)))
        # lateral malleolus: lower and more posterior than the medial one
        parts.append(_ellipsoid((-0.008, -0.004, 0.028), (0.012, 0.027, 0.008), n_theta))
    mesh = _join(parts)
    return Mesh(mesh.vertices * s, mesh.faces)


def mirror(mesh: Mesh) -> Mesh:
    """The left-leg bone from the right one: z → −z, face winding flipped (normals stay outward)."""
    v = mesh.vertices * np.array([1.0, 1.0, -1.0])
    return Mesh(v, mesh.faces[:, ::-1].copy())


def segment_lengths_m(height_m: float | None) -> tuple[float, float]:
    """(femur, tibia) lengths, m: the defaults, or scaled from the patient's height when it is known."""
    if height_m is None or not np.isfinite(height_m) or not 1.0 <= height_m <= 2.5:
        return FEMUR_LENGTH_M, TIBIA_LENGTH_M
    return FEMUR_HEIGHT_RATIO * height_m, TIBIA_HEIGHT_RATIO * height_m


def leg_meshes(side: str, height_m: float | None = None, *, n_theta: int = 24) -> dict[str, Mesh]:
    """``{"femur": Mesh, "tibia": Mesh}`` for the leg under study (``"right"`` or ``"left"``)."""
    if side not in ("right", "left"):
        raise ValueError(f"side must be 'right' or 'left', got {side!r}")
    femur_m, tibia_m = segment_lengths_m(height_m)
    meshes = {"femur": femur_mesh(femur_m, n_theta=n_theta), "tibia": tibia_mesh(tibia_m, n_theta=n_theta)}
    return {k: mirror(m) for k, m in meshes.items()} if side == "left" else meshes


# ---------------------------------------------------------------- key poses


def heading_free(q_earth_segment: FloatArray, q_heading_ref: FloatArray) -> FloatArray:
    """Remove the heading (rotation about earth z) that turns ``q_heading_ref``'s anterior axis (x) away
    from earth +x: returns ``q_z(−ψ) ⊗ q_earth_segment`` with ψ the azimuth of R(q_ref)·x.  (..., 4)."""
    x = quat.rotate(q_heading_ref, np.array([1.0, 0.0, 0.0]))
    psi = np.arctan2(x[..., 1], x[..., 0])
    q_z = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), -psi)
    return quat.multiply(q_z, q_earth_segment)


def key_pose_times_s(ri: ReportInput) -> list[float]:
    """The three instants drawn by :func:`key_poses`: onset, peak flexion, full extension (s).

    From ``results["cycles"]`` (first accepted cycle; events ``onset``, ``countermovement_peak``,
    ``far_reached`` or else ``far_left``).  When an event is missing, the instant falls back to the
    cycle's start, or the sample of largest / smallest flexion within the cycle (the whole task when
    there is no cycle)."""
    cycles = ri.results.get("cycles", {})
    names = list(cycles.get("events", []))
    events_s = cycles.get("events_s", [])
    bounds = cycles.get("boundaries_s", [])
    accepted = list(cycles.get("accepted_indices", range(len(bounds))))
    k = accepted[0] if accepted else (0 if bounds else None)

    def event(name: str) -> float | None:
        if k is None or name not in names or k >= len(events_s):
            return None
        value = events_s[k][names.index(name)]
        return float(value) if value is not None and np.isfinite(value) else None

    t = ri.t_s
    if k is not None and k < len(bounds) and None not in bounds[k]:
        inside = (t >= bounds[k][0]) & (t < bounds[k][1])
    else:
        inside = np.ones(len(t), dtype=bool)
    if not inside.any():
        inside[:] = True
    idx = np.flatnonzero(inside)
    flexion = ri.angles_deg[idx, 0]
    onset = event("onset")
    if onset is None:
        onset = float(t[idx[0]])
    peak = event("countermovement_peak")
    if peak is None:
        peak = float(t[idx[np.nanargmax(flexion)]])
    extension = event("far_reached")
    if extension is None:
        extension = event("far_left")
    if extension is None:
        extension = float(t[idx[np.nanargmin(flexion)]])
    return [onset, peak, extension]


def pose_vertices(meshes: dict[str, Mesh], q_earth_femur: FloatArray, q_earth_tibia: FloatArray,
                  tibia_length_m: float) -> dict[str, FloatArray]:
    """Vertices in earth axes (heading as given) with the ankle at the origin and the femur at the knee:
    tibia v_e = R_t·v;  femur v_e = R_t·[0, L_tibia, 0] + R_f·v."""
    r_t = quat.to_matrix(q_earth_tibia)
    r_f = quat.to_matrix(q_earth_femur)
    knee = r_t @ np.array([0.0, tibia_length_m, 0.0])
    return {"tibia": meshes["tibia"].vertices @ r_t.T, "femur": meshes["femur"].vertices @ r_f.T + knee}


@dataclass(frozen=True)
class KeyPoses:
    """The key-pose still as flat geometry, ready for any 2D renderer (PDF vectors, or a raster).

    triangles : (T, 3, 2) screen coordinates in metres (x right, y up), all three poses side by side,
        ordered far to near (draw in this order: painter's algorithm).
    rgb : (T, 3) Lambert-shaded colour of each triangle, 0..1.
    centres_x : (3,) the x of each pose's ankle (captions are centred there).
    flexion_deg : (3,) knee flexion at each instant (printed under each pose).
    ground : ``(x_lo, x_hi, y)`` the floor line.   view : ``(x_lo, x_hi, y_lo, y_hi)`` the framed area,
        twice as wide as high, equal scale on both axes.   height_m : femur + tibia length (text offsets).
    """

    triangles: FloatArray
    rgb: FloatArray
    centres_x: FloatArray
    flexion_deg: FloatArray
    ground: tuple[float, float, float]
    view: tuple[float, float, float, float]
    height_m: float


def key_poses(ri: ReportInput, *, n_theta: int = 16) -> KeyPoses:
    """The bones at the three key poses (module docstring), lateral view, as shaded 2D triangles.

    Orthographic projection on the sagittal plane (after heading removal: anterior = earth +x, up =
    earth z); back faces dropped, faces sorted far-to-near and Lambert-shaded.  Deterministic.
    """
    side = ri.results.get("side", ri.patient.side or "right")
    side = side if side in ("right", "left") else "right"
    femur_m, tibia_m = segment_lengths_m(ri.patient.height_m)
    meshes = leg_meshes(side, ri.patient.height_m, n_theta=n_theta)
    times = key_pose_times_s(ri)
    idx = [int(np.clip(np.searchsorted(ri.t_s, ts), 0, len(ri.t_s) - 1)) for ts in times]
    spacing_m = 0.62 * (femur_m + tibia_m)
    # lateral view.  Right leg: lateral is earth −y, the camera looks along +y, screen (x, z) = (X, Z).
    # Left leg: lateral is +y, camera looks along −y, screen = (−X, Z).  depth grows away from the camera.
    sx = 1.0 if side == "right" else -1.0
    view_dir = np.array([0.0, sx, 0.0])
    light = np.array([0.35 * sx, -0.8 * sx, 0.5])
    light /= np.linalg.norm(light)
    colour = np.array(BONE_RGB) / 255.0

    polys, rgbs = [], []
    for p, i in enumerate(idx):
        q_t = ri.q_earth_segment["tibia"][i]
        q_f = ri.q_earth_segment["femur"][i]
        verts = pose_vertices(meshes, heading_free(q_f, q_t), heading_free(q_t, q_t), tibia_m)
        tri = np.concatenate([verts[name][meshes[name].faces] for name in ("tibia", "femur")])
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        front = n @ view_dir < 0.0                               # back faces are hidden
        tri, n = tri[front], n[front]
        order = np.argsort(-(tri[:, :, 1].mean(axis=1) * sx), kind="stable")   # far first
        tri, n = tri[order], n[order]
        shade = 0.38 + 0.62 * np.clip(n @ light, 0.0, 1.0)
        polys.append(np.stack([sx * tri[:, :, 0] + p * spacing_m, tri[:, :, 2]], axis=2))
        rgbs.append(np.clip(colour[None, :] * shade[:, None], 0.0, 1.0))

    height_m = femur_m + tibia_m
    triangles = np.concatenate(polys)
    all_x = triangles[:, :, 0]
    x_lo, x_hi = min(all_x.min(), -0.25 * height_m), max(all_x.max(), 2 * spacing_m + 0.25 * height_m)
    y_lo, y_hi = -0.16 * height_m, 1.16 * height_m
    half_w = max((x_hi - x_lo) / 2.0 + 0.05, (y_hi - y_lo) / 0.5 / 2.0)      # equal scale, view is 2:1
    x_mid, y_mid = (x_lo + x_hi) / 2.0, (y_lo + y_hi) / 2.0
    return KeyPoses(triangles=triangles, rgb=np.concatenate(rgbs),
                    centres_x=np.arange(3, dtype=np.float64) * spacing_m,
                    flexion_deg=np.array([ri.angles_deg[i, 0] for i in idx], dtype=np.float64),
                    ground=(float(x_lo), float(x_hi), -0.03 * height_m),
                    view=(x_mid - half_w, x_mid + half_w, y_mid - half_w * 0.5, y_mid + half_w * 0.5),
                    height_m=height_m)
