"""The 3D view's first frame as a still picture, drawn by ChakaMo from the recorded scene itself (issue 17 §4).

viser's web client needs its 2.5 MB module evaluated, the recording fetched and decoded and its first WebGL frame
drawn, on the results page's own main thread beside plotly: 1.3 s or more on the clinic's two-core machine with
software WebGL, whatever the page does (``benchmarks/scene_first_frame.py --trace``).  The results page therefore
shows this picture in the 3D box first and hands over to viser's canvas as soon as the recording plays.  It is the
recording's own first state, not an illustration: the meshes (``MeshMessage`` vertices and faces, the binary
buffers of the ``.viser`` file), every node's orientation and position at t = 0 (``SetOrientationMessage`` /
``SetPositionMessage``; a node's pose is its parent's composed with its own, the scene tree of
:mod:`reports.scene`), the ground grid (``GridMessage``) and the initial camera (``SetCameraPositionMessage``,
``…LookAtMessage``, ``…UpDirectionMessage``), projected with viser's default perspective (vertical field of view
:data:`FOV_DEG`, the one three.js' canvas has when the server sets none).  What it leaves out is said here and in
the page's caption: viser's lighting (an environment map) and its angle label; the bones are flat-shaded in their
recorded colour with one light from the camera, ``shade = 0.35 + 0.65·|n·d|`` (n the face normal, d the view
direction), faces turned away from the camera left out as viser's one-sided material does, the rest painted far to near
(painter's algorithm, face centroids), drawn at twice the size and halved by 2 × 2 box averages (anti-aliasing).

Pinhole projection (camera frame: x right, y up, looking along −z; f = (H/2) / tan(FOV/2))::

    u = W/2 + f·x_c / (−z_c),   v = H/2 − f·y_c / (−z_c)
"""

from __future__ import annotations

import functools
import io
from typing import Any

import msgspec
import msgspec.msgpack
import numpy as np

from estimators import quaternion as quat

#: viser's client camera when the server sets no field of view (react-three-fiber's default), degrees, vertical
FOV_DEG = 75.0
#: the picture's size (2:1: the page shows it with ``object-fit: cover`` in a box of 16:9 to ~2:1, so its height
#: is the box's height and the vertical field of view stays viser's)
WIDTH, HEIGHT = 960, 480
NEAR_M = 0.01
GRID_RGB = (200, 200, 200)
SECTION_RGB = (140, 140, 140)
#: the viser major version whose recordings the still reads (the dependency is ``viser>=1.0,<2``; 0.x meshes had
#: no ``props``)
VISER_MAJOR = "1"
#: caps on what one recording may ask the still to draw (the bones have a few thousand of each; a grid line per
#: cell of the ground's 10 cm grid: a few hundred)
MAX_VERTICES, MAX_FACES, MAX_GRID_LINES = 200_000, 400_000, 2_000


def _resolve(obj: Any, buffers: list[memoryview], dtypes: dict) -> Any:
    """Placeholders ``{"__binary_index": i, "dtype": ...}`` (viser's binary arrays) replaced by numpy arrays."""
    if isinstance(obj, dict):
        if "__binary_index" in obj:
            return np.frombuffer(buffers[obj["__binary_index"]], dtype=np.dtype(obj["dtype"]))
        return {k: _resolve(v, buffers, dtypes) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_resolve(v, buffers, dtypes) for v in obj]
    return obj


class _Recording(msgspec.Struct):
    """The msgpack part of a ``.viser`` recording as the still reads it: each message's time decoded, the message
    itself kept as its raw msgpack bytes (``msgspec.Raw``), so only the messages of t = 0 are decoded."""
    messages: list[tuple[float, msgspec.Raw]]
    viserVersion: str = ""  # noqa: N815 (the file's own field name)
    binaryBufferLengths: list[int] = []  # noqa: N815, RUF012


def _mesh(props: dict, name: str) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """A ``MeshMessage``'s (vertices (n, 3), faces (m, 3), rgb), checked: at most :data:`MAX_VERTICES` /
    :data:`MAX_FACES`, every face index a vertex."""
    vertices = np.asarray(props["vertices"], dtype=float).reshape(-1, 3)
    faces = np.asarray(props["faces"], dtype=np.int64).reshape(-1, 3)
    if len(vertices) > MAX_VERTICES or len(faces) > MAX_FACES:
        raise ValueError(f"mesh {name}: {len(vertices)} vertices, {len(faces)} faces, more than the still draws "
                         f"({MAX_VERTICES}, {MAX_FACES})")
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise ValueError(f"mesh {name}: a face names a vertex it does not have")
    return vertices, faces, tuple(int(c) for c in props.get("color") or (200, 200, 200))


def first_state(raw: bytes) -> dict[str, Any]:
    """The recording's state at t = 0: ``{"meshes": {path: (vertices (n, 3), faces (m, 3), rgb)}, "wxyz": {path:
    (4,)}, "position": {path: (3,)}, "grids": {path: props}, "camera": {"position", "look_at", "up"}}``.

    Bounded: the payload is decompressed through :func:`reports.scene.inner_bytes` (at most
    :data:`reports.scene.MAX_INNER_BYTES`), only the messages of t = 0 are decoded, meshes and grids are capped
    (:data:`MAX_VERTICES`, :data:`MAX_FACES`, :data:`MAX_GRID_LINES`).  ``ValueError`` for a recording the still
    cannot read: another viser major version than :data:`VISER_MAJOR`, a message of a shape it does not know."""
    from reports.scene import inner_bytes

    inner = inner_bytes(raw)
    n = int.from_bytes(inner[:8], "little")
    try:
        recording = msgspec.msgpack.decode(memoryview(inner)[8:8 + n], type=_Recording)
    except msgspec.DecodeError as exc:
        raise ValueError(f"not a .viser recording the still can read: {exc}") from exc
    major = recording.viserVersion.split(".")[0]
    if major != VISER_MAJOR:
        raise ValueError(f"the recording was made by viser {recording.viserVersion or '(unknown)'}; the still reads "
                         f"viser {VISER_MAJOR}.x")
    offset = 8 + n
    buffers = []
    for size in recording.binaryBufferLengths:
        offset += (8 - offset % 8) % 8
        buffers.append(memoryview(inner)[offset:offset + size])
        offset += size
    state: dict[str, Any] = {"meshes": {}, "wxyz": {}, "position": {}, "grids": {}, "camera": {}}
    try:
        for t_s, encoded in recording.messages:
            if t_s > 0:
                break
            message = msgspec.msgpack.decode(encoded)
            kind, name = message.get("type"), message.get("name")
            if kind == "MeshMessage":
                state["meshes"][name] = _mesh(_resolve(message["props"], buffers, {}), name)
            elif kind == "SetOrientationMessage":
                state["wxyz"][name] = np.asarray(message["wxyz"], dtype=float).reshape(4)
            elif kind == "SetPositionMessage":
                state["position"][name] = np.asarray(message["position"], dtype=float).reshape(3)
            elif kind == "GridMessage":
                state["grids"][name] = dict(message["props"])
            elif kind == "SetCameraPositionMessage":
                state["camera"]["position"] = np.asarray(message["position"], dtype=float).reshape(3)
            elif kind == "SetCameraLookAtMessage":
                state["camera"]["look_at"] = np.asarray(message["look_at"], dtype=float).reshape(3)
            elif kind == "SetCameraUpDirectionMessage":
                state["camera"]["up"] = np.asarray(message["position"], dtype=float).reshape(3)
    except (KeyError, IndexError, TypeError, AttributeError, msgspec.DecodeError) as exc:
        raise ValueError(f"a message of the recording's start the still cannot read: {exc!r}") from exc
    return state


def world_points(state: dict[str, Any], path: str, points: np.ndarray) -> np.ndarray:
    """``points`` (n, 3) of node ``path`` in the world frame: the node's pose composed with every ancestor's
    (``/a/b/c``: ``/a`` ∘ ``/a/b`` ∘ ``/a/b/c``), each ``p_parent = R(wxyz)·p_local + position``.  The root's
    orientation (viser's own z-up to three.js y-up turn, node ``""``) is not applied: the camera is in the same
    world frame."""
    out = np.asarray(points, dtype=float)
    parts = path.strip("/").split("/")
    for k in range(len(parts), 0, -1):
        node = "/" + "/".join(parts[:k])
        q = state["wxyz"].get(node)
        if q is not None:
            out = quat.rotate(np.broadcast_to(quat.normalize(q), (len(out), 4)), out)
        out = out + state["position"].get(node, np.zeros(3))
    return out


def _camera(state: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """(R, eye): rows of R are the camera's right, up and backward axes in the world frame."""
    cam = state["camera"]
    eye = cam.get("position", np.array([3.0, 3.0, 3.0]))
    target = cam.get("look_at", np.zeros(3))
    up = cam.get("up", np.array([0.0, 0.0, 1.0]))
    back = eye - target
    back = back / np.linalg.norm(back)
    right = np.cross(up, back)
    right = right / np.linalg.norm(right)
    return np.stack([right, np.cross(back, right), back]), eye


def _grid_segments(props: dict, origin: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, bool]]:
    """The grid's lines (plane ``xy``, centred on ``origin``): (start, end, is a section line)."""
    w, h = float(props.get("width", 1.0)), float(props.get("height", 1.0))
    cell, section = float(props.get("cell_size", 0.1)), float(props.get("section_size", 1.0))
    if not all(np.isfinite(x) and x > 0 for x in (w, h, cell, section)):
        raise ValueError(f"a grid of width {w}, height {h}, cell {cell}, section {section}: not positive and finite")
    if w / cell + h / cell + 2 > MAX_GRID_LINES:
        raise ValueError(f"a grid of {w} × {h} with cell {cell}: more than {MAX_GRID_LINES} lines")
    lines = []
    for along, span, size in ((0, w, h), (1, h, w)):
        for k in range(int(round(span / cell)) + 1):
            c = -span / 2 + k * cell
            a, b = np.zeros(3), np.zeros(3)
            a[along], b[along] = c, c
            a[1 - along], b[1 - along] = -size / 2, size / 2
            lines.append((origin + a, origin + b, abs(c / section - round(c / section)) < 1e-6))
    return lines


@functools.lru_cache(maxsize=16)
def still_png(raw: bytes, width: int = WIDTH, height: int = HEIGHT) -> bytes:
    """The first frame of the ``.viser`` recording ``raw`` as a PNG of ``width`` × ``height`` (module docstring);
    cached per recording (the same bytes draw the same picture)."""
    from PIL import Image, ImageDraw

    state = first_state(raw)
    if not state["meshes"]:
        raise ValueError("the recording has no mesh at its start: nothing to draw")
    scale = 2
    W, H = width * scale, height * scale
    f = (H / 2) / np.tan(np.radians(FOV_DEG) / 2)
    R, eye = _camera(state)

    def project(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c = (p - eye) @ R.T
        depth = -c[:, 2]
        safe = np.maximum(depth, NEAR_M)
        return np.stack([W / 2 + f * c[:, 0] / safe, H / 2 - f * c[:, 1] / safe], axis=1), depth

    image = Image.new("RGB", (W, H), (255, 255, 255))
    draw = ImageDraw.Draw(image)
    for path, props in state["grids"].items():
        for a, b, major in _grid_segments(props, np.zeros(3)):
            ends = world_points(state, path, np.stack([a, b]))
            uv, depth = project(ends)
            if (depth > NEAR_M).all():
                draw.line([tuple(uv[0]), tuple(uv[1])], fill=SECTION_RGB if major else GRID_RGB, width=scale)
    triangles = []
    for path, (vertices, faces, rgb) in state["meshes"].items():
        world = world_points(state, path, vertices)
        uv, depth = project(world)
        tri = world[faces]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        view = eye - tri.mean(axis=1)
        view /= np.linalg.norm(view, axis=1, keepdims=True)
        facing = (normal * view).sum(axis=1)
        shade = 0.35 + 0.65 * np.abs(facing)
        # viser's meshes are one-sided (``side: front``): faces turned away from the camera are not drawn
        keep = (depth[faces] > NEAR_M).all(axis=1) & (facing > 0)
        colours = (np.asarray(rgb, dtype=float)[None, :] * shade[:, None]).clip(0, 255).astype(int)
        triangles.append((depth[faces].mean(axis=1)[keep], uv[faces][keep], colours[keep]))
    depth = np.concatenate([t[0] for t in triangles])
    order = np.argsort(-depth)
    polygons = np.concatenate([t[1] for t in triangles])[order].reshape(-1, 6).tolist()
    fills = [tuple(c) for c in np.concatenate([t[2] for t in triangles])[order].tolist()]
    for polygon, fill in zip(polygons, fills):
        draw.polygon(polygon, fill=fill)
    out = io.BytesIO()
    image.reduce(scale).save(out, format="PNG", compress_level=1)
    return out.getvalue()


__all__ = ["FOV_DEG", "HEIGHT", "MAX_FACES", "MAX_GRID_LINES", "MAX_VERTICES", "VISER_MAJOR", "WIDTH", "first_state",
           "still_png", "world_points"]
