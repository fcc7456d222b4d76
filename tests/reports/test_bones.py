"""Procedural bone meshes and the key-poses still (reports/bones.py)."""

from __future__ import annotations


import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from estimators import quaternion as quat
from reports import bones
from reports.model import Patient, ReportInput

EVENTS = ["onset", "countermovement_peak", "far_reached", "far_left", "rest_reached"]


def _leg_quaternions(flexion_deg, heading_deg, tibia_tilt_deg):
    """q_earth_tibia, q_earth_femur for a leg standing on the ground: the tibia tilted forward by
    tibia_tilt, the femur flexed by flexion relative to it (rotation about the segment z axis)."""
    n = len(flexion_deg)
    z = np.array([0.0, 0.0, 1.0])
    q_heading = quat.from_axis_angle(z, np.deg2rad(heading_deg))
    q_upright = np.tile(quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2), (n, 1))  # y_seg → up
    q_tilt = quat.from_axis_angle(z, -np.deg2rad(tibia_tilt_deg))      # top of the tibia forwards
    q_tibia = quat.multiply(q_heading, quat.multiply(q_upright, q_tilt))
    q_femur = quat.multiply(q_tibia, quat.from_axis_angle(z, np.deg2rad(flexion_deg)))
    return q_tibia, q_femur


def make_input(side="right", events=True, n_cycles=2, fs_hz=100.0, height_m=None) -> ReportInput:
    """Small synthetic session: n_cycles of 60° → 70° → 0° → 60° flexion, 3 s each."""
    cycle_s = 3.0
    t = np.arange(0.0, 1.0 + n_cycles * cycle_s + 1.0, 1.0 / fs_hz)
    u = np.clip((t - 1.0) / cycle_s, 0.0, n_cycles)
    phase = u % 1.0
    flexion = np.where(phase < 0.15, 60.0 + 10.0 * np.sin(np.pi * phase / 0.3),
                       np.interp(phase, [0.15, 0.45, 0.7, 1.0], [70.0, 0.0, 0.0, 60.0]))
    flexion[(t < 1.0) | (u >= n_cycles)] = 60.0
    heading = 30.0 + 5.0 * np.sin(t)
    q_tibia, q_femur = _leg_quaternions(flexion, heading, 0.45 * flexion)
    angles = np.stack([flexion, np.full_like(t, 2.0), np.full_like(t, 5.0)], axis=1)
    bounds = [[1.0 + k * cycle_s, 1.0 + (k + 1) * cycle_s] for k in range(n_cycles)]
    cycles = {"detected": n_cycles, "accepted": n_cycles, "rejected": [], "boundaries_s": bounds,
              "accepted_indices": list(range(n_cycles))}
    if events:
        cycles["events"] = EVENTS
        cycles["events_s"] = [[b[0], b[0] + 0.15 * cycle_s, b[0] + 0.45 * cycle_s, b[0] + 0.7 * cycle_s, b[1]]
                              for b in bounds]
    results = {"side": side, "task": "step_up", "angles": ["flexion", "adduction", "internal_rotation"],
               "cycles": cycles}
    q_id = np.array([1.0, 0.0, 0.0, 0.0])
    return ReportInput(results=results, t_s=t, angles_deg=angles,
                       q_earth_sensor={"thigh": q_femur.copy(), "shank": q_tibia.copy()},
                       q_earth_segment={"femur": q_femur, "tibia": q_tibia},
                       q_sensor_segment={"thigh": q_id, "shank": q_id},
                       patient=Patient(side=side, height_m=height_m), language="en")


def _components(mesh):
    f = mesh.faces
    rows = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    cols = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(mesh.vertices),) * 2)
    return connected_components(graph, directed=False)[1]


def _signed_volume(vertices, faces):
    v = vertices[faces]
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)


ALL_MESHES = {
    "femur": lambda: bones.femur_mesh(),
    "tibia": lambda: bones.tibia_mesh(),
    "femur_left": lambda: bones.mirror(bones.femur_mesh()),
    "tibia_left": lambda: bones.mirror(bones.tibia_mesh()),
    "femur_coarse": lambda: bones.femur_mesh(n_theta=8),
}


@pytest.mark.parametrize("name", sorted(ALL_MESHES))
def test_every_component_is_closed_consistently_wound_and_outward(name):
    mesh = ALL_MESHES[name]()
    f = mesh.faces
    assert f.dtype.kind == "i" and f.min() >= 0 and f.max() < len(mesh.vertices)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    edges = {tuple(e) for e in directed.tolist()}
    assert len(edges) == len(directed), "a directed edge is used twice: inconsistent winding"
    assert all((b, a) in edges for a, b in edges), "an edge has no opposite half-edge: surface not closed"
    labels = _components(mesh)
    face_label = labels[f[:, 0]]
    for c in np.unique(face_label):
        vol = _signed_volume(mesh.vertices, f[face_label == c])
        assert vol > 1e-7, f"component {c} has signed volume {vol}: normals point inwards"
    # no degenerate triangles
    assert np.linalg.norm(np.cross(*(mesh.vertices[f[:, 1:]] - mesh.vertices[f[:, :1]]).transpose(1, 0, 2)),
                          axis=1).min() > 1e-12


def test_femur_shape_and_size_are_anatomical():
    L = 0.42
    m = bones.femur_mesh(L)
    v = m.vertices
    head = v[np.linalg.norm(v - [0.0, L, 0.0], axis=1) < 0.0236]
    assert len(head) > 50                                     # the head is a sphere on the hip centre
    assert L + 0.015 < v[:, 1].max() < L + 0.035              # top of the head
    assert -0.01 < v[:, 1].min() < 0.005                      # condyles reach the knee joint centre
    distal = v[v[:, 1] < 0.05]
    assert 0.065 < np.ptp(distal[:, 2]) < 0.10                # condylar width (medio-lateral)
    assert 0.045 < np.ptp(distal[:, 0]) < 0.08                # condylar depth (antero-posterior)
    mid = v[np.abs(v[:, 1] - L / 2) < 0.01]
    mid = mid[np.abs(mid[:, 2] - np.median(mid[:, 2])) < 0.03]
    assert 0.02 < np.ptp(mid[:, 0]) < 0.04                    # shaft diameter
    # greater trochanter lateral (+z, right leg) of the head, at about the head's height
    prox = v[v[:, 1] > L - 0.06]
    assert prox[:, 2].max() > 0.065 and prox[:, 2].min() < -0.02


def test_tibia_shape_and_size_are_anatomical():
    L = 0.40
    m = bones.tibia_mesh(L)
    v = m.vertices
    assert L - 0.012 < v[:, 1].max() < L + 0.002              # plateau just below the knee centre
    plateau = v[v[:, 1] > L - 0.03]
    assert 0.065 < np.ptp(plateau[:, 2]) < 0.09               # plateau width
    low = v[v[:, 1] < 0.0]
    assert low[:, 2].min() < -0.025 and low[:, 2].max() > 0.03  # medial and lateral malleoli
    assert v[:, 1].min() < -0.02                              # malleoli reach below the ankle centre
    no_fibula = bones.tibia_mesh(L, fibula=False).vertices
    assert no_fibula[no_fibula[:, 1] < 0.0][:, 2].max() < 0.01  # lateral malleolus belongs to the fibula


def test_left_is_the_mirror_of_the_right():
    for right in (bones.femur_mesh(), bones.tibia_mesh()):
        left = bones.mirror(right)
        np.testing.assert_array_equal(left.vertices, right.vertices * [1.0, 1.0, -1.0])
        np.testing.assert_array_equal(left.faces, right.faces[:, ::-1])
        np.testing.assert_allclose(left.normals(), right.normals() * [1.0, 1.0, -1.0], atol=1e-12)
    legs = bones.leg_meshes("left")
    np.testing.assert_array_equal(legs["femur"].vertices, bones.mirror(bones.femur_mesh()).vertices)
    with pytest.raises(ValueError, match="side"):
        bones.leg_meshes("both")


def test_lengths_scale_with_height_and_are_validated():
    assert bones.segment_lengths_m(None) == (bones.FEMUR_LENGTH_M, bones.TIBIA_LENGTH_M)
    assert bones.segment_lengths_m(1.80) == pytest.approx((0.245 * 1.8, 0.246 * 1.8))
    assert bones.segment_lengths_m(17.0) == (bones.FEMUR_LENGTH_M, bones.TIBIA_LENGTH_M)  # not a height
    big = bones.femur_mesh(0.84)
    np.testing.assert_allclose(big.vertices, 2.0 * bones.femur_mesh(0.42).vertices)
    with pytest.raises(ValueError, match="length_m"):
        bones.tibia_mesh(0.0)
    with pytest.raises(ValueError, match="n_theta"):
        bones.femur_mesh(n_theta=3)


def test_pose_chain_anchors_tibia_at_ankle_and_femur_at_knee():
    q_t, q_f = _leg_quaternions(np.array([40.0]), np.array([70.0]), np.array([20.0]))
    meshes = {"femur": bones.Mesh(np.array([[0.0, 0.0, 0.0], [0.0, 0.3, 0.0]]), np.zeros((0, 3), int)),
              "tibia": bones.Mesh(np.array([[0.0, 0.0, 0.0], [0.0, 0.4, 0.0]]), np.zeros((0, 3), int))}
    v = bones.pose_vertices(meshes, q_f[0], q_t[0], 0.4)
    np.testing.assert_allclose(v["tibia"][0], 0.0, atol=1e-15)          # ankle fixed
    np.testing.assert_allclose(v["femur"][0], v["tibia"][1], atol=1e-12)  # femur origin on the knee
    knee_to_hip = v["femur"][1] - v["femur"][0]
    ankle_to_knee = v["tibia"][1]
    cos = knee_to_hip @ ankle_to_knee / 0.3 / 0.4
    assert np.rad2deg(np.arccos(cos)) == pytest.approx(40.0, abs=1e-9)  # the knee angle is kept
    # heading removal: the tibia's anterior axis points to earth +x, its long axis stays as it was
    q_free = bones.heading_free(q_t[0], q_t[0])
    x = quat.rotate(q_free, np.array([1.0, 0.0, 0.0]))
    assert abs(x[1]) < 1e-12 and x[0] > 0
    y0 = quat.rotate(q_t[0], np.array([0.0, 1.0, 0.0]))
    y1 = quat.rotate(q_free, np.array([0.0, 1.0, 0.0]))
    assert y1[2] == pytest.approx(y0[2], abs=1e-12)


def test_key_pose_times_come_from_the_cycle_events():
    ri = make_input()
    assert bones.key_pose_times_s(ri) == pytest.approx([1.0, 1.45, 2.35])
    ri.results["cycles"]["accepted_indices"] = [1]
    assert bones.key_pose_times_s(ri) == pytest.approx([4.0, 4.45, 5.35])
    ri.results["cycles"]["events_s"][1][2] = None                    # no far_reached: far_left
    assert bones.key_pose_times_s(ri)[2] == pytest.approx(6.1)


def test_key_pose_times_fall_back_to_the_flexion_extremes_without_events():
    ri = make_input(events=False)
    onset, peak, extension = bones.key_pose_times_s(ri)
    assert onset == pytest.approx(1.0)
    assert ri.angles_deg[np.searchsorted(ri.t_s, peak), 0] == pytest.approx(70.0, abs=0.5)
    assert ri.angles_deg[np.searchsorted(ri.t_s, extension), 0] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("side", ["right", "left"])
def test_key_poses_are_three_side_by_side_poses(side):
    ri = make_input(side=side, height_m=1.7)
    kp = bones.key_poses(ri)
    assert kp.triangles.shape[1:] == (3, 2) and len(kp.rgb) == len(kp.triangles) > 1000
    x = kp.triangles[:, :, 0].mean(axis=1)
    # three poses around their centres, each pose's bones nearer its own centre than the others'
    nearest = np.argmin(np.abs(x[:, None] - kp.centres_x[None, :]), axis=1)
    assert set(np.unique(nearest)) == {0, 1, 2}
    assert np.all((kp.triangles[:, :, 0] >= kp.view[0]) & (kp.triangles[:, :, 0] <= kp.view[1]))
    assert np.all((kp.triangles[:, :, 1] >= kp.view[2]) & (kp.triangles[:, :, 1] <= kp.view[3]))


@pytest.mark.parametrize("side", ["right", "left"])
def test_key_poses_geometry_is_framed_shaded_and_at_the_key_instants(side):
    ri = make_input(side=side, height_m=1.7)
    kp = bones.key_poses(ri)
    x0, x1, y0, y1 = kp.view
    assert kp.triangles.ndim == 3 and kp.triangles.shape[1:] == (3, 2) and len(kp.triangles) > 1000
    assert len(kp.rgb) == len(kp.triangles) and (kp.rgb >= 0).all() and (kp.rgb <= 1).all()
    assert (x1 - x0) == pytest.approx(2 * (y1 - y0))                      # 2:1 frame, equal scale
    xs, ys = kp.triangles[..., 0], kp.triangles[..., 1]
    assert x0 <= xs.min() and xs.max() <= x1 and y0 <= ys.min() and ys.max() <= y1
    assert kp.ground[2] < ys.min() + 0.05 and ys.max() < 1.04 * kp.height_m   # on the floor, below the titles
    # three legs side by side, each around its centre; flexion printed = the angle at the key instants
    for c in kp.centres_x:
        assert np.any(np.abs(xs.mean(axis=1) - c) < 0.2)
    idx = [int(np.searchsorted(ri.t_s, t)) for t in bones.key_pose_times_s(ri)]
    assert kp.flexion_deg == pytest.approx(ri.angles_deg[idx, 0])
    again = bones.key_poses(ri)
    assert np.array_equal(again.triangles, kp.triangles) and np.array_equal(again.rgb, kp.rgb)
