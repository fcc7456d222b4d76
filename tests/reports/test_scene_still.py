"""The still first frame (reports/scene_still.py) reads the recording's own first state and draws it where viser's
camera sees it.  Truth: the scene's input (:class:`reports.scene.SceneData`: the meshes of :mod:`reports.bones`, the
first sample's segment orientations, the heading removal, the tibia length), not the recording path under test."""

from __future__ import annotations

import io

import numpy as np
import pytest
from test_scene import make_input

from estimators import quaternion as quat
from reports.scene import SceneData, scene_bytes
from reports.scene_still import FOV_DEG, HEIGHT, WIDTH, first_state, still_png, world_points

pytest.importorskip("viser")


@pytest.fixture(scope="module")
def recorded():
    ri = make_input(side="left")
    return SceneData.from_report_input(ri), scene_bytes(ri)


def test_first_state_holds_the_meshes_and_poses_of_the_first_sample(recorded):
    data, raw = recorded
    state = first_state(raw)
    for path, seg in (("/knee/tibia", "tibia"), ("/knee/tibia/femur", "femur")):
        vertices, faces, _ = state["meshes"][path]
        np.testing.assert_allclose(vertices, data.meshes[seg].vertices, atol=1e-6)   # float32 in the file
        np.testing.assert_array_equal(faces, data.meshes[seg].faces)
    # the knee joint centre (the femur's origin) in the world: heading removal ∘ tibia orientation · [0, L, 0]
    knee = quat.rotate(quat.multiply(data.q_view_earth, data.q_earth_tibia[0]), np.array([0.0, data.tibia_length_m, 0.0]))
    np.testing.assert_allclose(world_points(state, "/knee/tibia/femur", np.zeros((1, 3)))[0], knee, atol=1e-9)
    # a femur vertex: the chain femur → tibia → knee frame
    v = data.meshes["femur"].vertices[:1]
    q_earth_femur = quat.multiply(data.q_view_earth, quat.multiply(data.q_earth_tibia[0], data.q_tibia_femur[0]))
    np.testing.assert_allclose(world_points(state, "/knee/tibia/femur", v)[0], quat.rotate(q_earth_femur, v[0]) + knee,
                               atol=1e-6)


def test_the_still_shows_bone_at_the_projected_knee_and_is_white_far_from_it(recorded):
    from PIL import Image

    data, raw = recorded
    img = np.asarray(Image.open(io.BytesIO(still_png(raw))).convert("RGB")).astype(int)
    assert img.shape == (HEIGHT, WIDTH, 3)
    state = first_state(raw)
    knee = world_points(state, "/knee/tibia/femur", np.zeros((1, 3)))[0]
    # the pinhole of the module docstring, built here from the recorded camera
    cam = state["camera"]
    back = (cam["position"] - cam["look_at"]) / np.linalg.norm(cam["position"] - cam["look_at"])
    right = np.cross(cam["up"], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    c = knee - cam["position"]
    f = (HEIGHT / 2) / np.tan(np.radians(FOV_DEG) / 2)
    u = WIDTH / 2 + f * (c @ right) / -(c @ back)
    v = HEIGHT / 2 - f * (c @ up) / -(c @ back)
    patch = img[int(v) - 2:int(v) + 3, int(u) - 2:int(u) + 3]
    assert (np.abs(patch - 255).sum(axis=2) > 30).any(), "no bone drawn at the knee's projection"
    assert (img[:20, :20] == 255).all()   # the sky corner stays white: no bone there


def test_a_recording_without_meshes_is_refused():
    import viser

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        raw = server.get_scene_serializer().serialize()
    finally:
        server.stop()
    with pytest.raises(ValueError, match="no mesh"):
        still_png(raw)
