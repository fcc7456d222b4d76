"""The still first frame (reports/scene_still.py) reads the recording's own first state and draws it where viser's
camera sees it.  Truth: the scene's input (:class:`reports.scene.SceneData`: the meshes of :mod:`reports.bones`, the
first sample's segment orientations, the heading removal, the tibia length), not the recording path under test.

A recording the still cannot draw is refused with one ``ValueError`` (the route answers it as ``store.no_still``),
and what a crafted recording can make it do is bounded: files built from a real recording with one thing changed
(the size its zstd frame states, a grid's cell, a mesh, the viser version) are refused with little memory
(tracemalloc) and few grid lines, not timed."""

from __future__ import annotations

import io
import tracemalloc

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


def _rewrite(raw: bytes, edit) -> bytes:
    """``raw`` with its msgpack part and binary buffers changed by ``edit(recording, buffers)`` (in place), repacked in the same layout
    (``[u64 size][zstd([u64 n][msgpack][8-byte aligned buffers])]``, reports/scene.py's docstring)."""
    import msgspec.msgpack
    import zstandard

    from reports.scene import inner_payload

    inner = inner_payload(raw)[0]
    n = int.from_bytes(inner[:8], "little")
    recording = msgspec.msgpack.decode(inner[8:8 + n])
    offset, buffers = 8 + n, []
    for size in recording["binaryBufferLengths"]:
        offset += (8 - offset % 8) % 8
        buffers.append(inner[offset:offset + size])
        offset += size
    edit(recording, buffers)
    packed = msgspec.msgpack.encode(recording)
    out = bytearray(len(packed).to_bytes(8, "little") + packed)
    for buf in buffers:
        out += b"\0" * ((8 - len(out) % 8) % 8) + buf
    return len(out).to_bytes(8, "little") + zstandard.ZstdCompressor().compress(bytes(out))


def _messages(recording, kind):
    return [m for t, m in recording["messages"] if t == 0 and m.get("type") == kind]


def test_the_rewrite_helper_keeps_a_recording_drawable(recorded):
    _, raw = recorded
    assert still_png(_rewrite(raw, lambda rec, buffers: None)) == still_png(raw)


def _peak_bytes(call) -> int:
    tracemalloc.start()
    try:
        call()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


def test_a_frame_stating_a_huge_size_is_not_decompressed_beyond_the_cap():
    """A zstd frame whose header states its own content size (80 MB of zeros, ~2.6 kB compressed) behind a file
    header stating 1 kB: zstd's output limit is ignored for such a frame, the streaming read is not."""
    import zstandard

    from reports.scene import read_scene

    size = 80 * 2**20
    packer = zstandard.ZstdCompressor().compressobj(size=size)
    frame = b"".join(packer.compress(bytes(2**20)) for _ in range(size // 2**20)) + packer.flush()
    assert zstandard.frame_content_size(frame) == size and len(frame) < 10_000
    bomb = (1000).to_bytes(8, "little") + frame
    peak = _peak_bytes(lambda: pytest.raises(ValueError, read_scene, bomb))
    assert peak < 4 * 2**20, peak
    with pytest.raises(ValueError, match="more than"):
        first_state((size).to_bytes(8, "little") + frame)   # a stated size over MAX_INNER_BYTES: not even read


def test_a_grid_of_too_many_lines_is_refused(recorded, monkeypatch):
    """A ground grid of 2 m with a 20 µm cell would be 200,000 lines: refused, and no line is drawn (counted)."""
    import reports.scene_still as still

    _, raw = recorded

    def tiny_cell(rec, buffers):
        _messages(rec, "GridMessage")[0]["props"]["cell_size"] = 2e-5

    crafted = _rewrite(raw, tiny_cell)
    drawn = []
    real = still._grid_segments
    monkeypatch.setattr(still, "_grid_segments", lambda *a: drawn.extend(real(*a)) or drawn)
    with pytest.raises(ValueError, match="lines"):
        still_png(crafted)
    assert drawn == []


def test_meshes_beyond_the_caps_or_with_faces_out_of_range_are_refused(recorded):
    _, raw = recorded

    def faces_of_the_tibia(rec, buffers):   # the femur (2,438 vertices) given the tibia's faces (up to 2,479)
        tibia, femur = _messages(rec, "MeshMessage")
        femur["props"]["faces"] = dict(tibia["props"]["faces"])

    def too_many_vertices(rec, buffers):    # the femur given a vertex buffer of MAX_VERTICES + 1 points
        from reports.scene_still import MAX_VERTICES

        buffers.append(np.zeros((MAX_VERTICES + 1, 3), dtype=np.float32).tobytes())
        rec["binaryBufferLengths"].append(len(buffers[-1]))
        _messages(rec, "MeshMessage")[1]["props"]["vertices"]["__binary_index"] = len(buffers) - 1

    with pytest.raises(ValueError, match="names a vertex"):
        still_png(_rewrite(raw, faces_of_the_tibia))
    with pytest.raises(ValueError, match="vertices"):
        still_png(_rewrite(raw, too_many_vertices))


def test_another_viser_major_version_or_an_unknown_message_shape_is_refused(recorded):
    _, raw = recorded

    def old_version(rec, buffers):
        rec["viserVersion"] = "0.2.23"

    def no_props(rec, buffers):   # viser 0.x's MeshMessage: its fields at the top, no ``props``
        mesh = _messages(rec, "MeshMessage")[0]
        mesh.update(mesh.pop("props"))

    with pytest.raises(ValueError, match="viser 0.2.23"):
        still_png(_rewrite(raw, old_version))
    with pytest.raises(ValueError, match="cannot read"):
        still_png(_rewrite(raw, no_props))
