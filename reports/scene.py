"""The 3D knee: femur and tibia driven by the segment orientations, live (viser) and recorded.

Scene tree (viser node paths; a child moves with its parent)::

    /knee                 frame: heading removal, q_z(−ψ) with ψ the task's mean azimuth of the tibia's
                          anterior axis, so the leg faces +x and the default camera sees it from the side
    /knee/tibia           tibia mesh, origin at the ankle joint centre (anchored at /knee's origin),
                          wxyz = q_earth_tibia
    /knee/tibia/femur     femur mesh, origin at the knee joint centre, position [0, L_tibia, 0] in the
                          tibia frame, wxyz = q_tibia_femur = q_earth_tibia* ⊗ q_earth_femur
    /knee/angles          label with the three angles (recorded scene only; the live viewer shows them
                          in the GUI)
    /ground               grid under the ankle

so the tibia is anchored at the ankle and the femur attached at the knee; viser's ``wxyz`` is the
rotation *to the parent frame from the local frame* (R_pl), scalar first — exactly our ``q_parent_local``
convention (DESIGN §3), so segment quaternions are passed unchanged.  Viser's world is z-up like ENU.
Meshes: :mod:`reports.bones` (mirrored for the left leg).

Live (:func:`build_scene`): a GUI folder with play/pause, speed, time slider, a jump-to-cycle dropdown
(accepted cycles) and the three angles as read-only numbers; each frame's updates are grouped in
``server.atomic()``.  :meth:`KneeScene.run` is the playback loop (``chakamo view``).

Recorded (:func:`export_scene`): the same nodes, then the task resampled at ``rate_hz`` (25 Hz) — per
frame two orientation messages (tibia, femur), the angle label every ``label_every`` frames — separated
by ``serializer.insert_sleep(1 / rate_hz)`` on viser's scene serialiser (``server.get_scene_serializer()``
on a throw-away server bound to 127.0.0.1, port 0; GUI messages are not recorded by viser).
``serializer.serialize()`` gives the ``.viser`` bytes: ``[u64 inner size][zstd([u64 n][msgpack
{durationSeconds, messages: [(t_s, message)], viserVersion, binaryBufferLengths}][aligned buffers])]``
(read back by :func:`read_scene`).

Playing a ``.viser`` file without a live server: viser ships its built web client as ONE self-contained
file, ``viser/client/build/index.html`` inside the installed package (:func:`static_client_path`; no
CDN, the default environment map is inlined).  Serve that file and the ``.viser`` file over HTTP from
the same origin and open ``index.html?playbackPath=<url of scene.viser>`` — the client downloads the
recording and shows its own play/pause and time bar.  Alternatively :func:`scene_html` embeds the
recording in a copy of the client (viser's ``as_html``: the bytes as base64 in
``window.__VISER_EMBED_DATA__``), a single offline HTML file.
"""

from __future__ import annotations

import contextlib
import io
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimators import quaternion as quat

from . import bones, i18n
from .model import ANGLES, ReportInput

FloatArray = NDArray[np.float64]

#: frame rate of the recorded scene, Hz
SCENE_RATE_HZ = 25.0
#: the angle label of the recorded scene is updated every this many frames (5 Hz at 25 Hz)
LABEL_EVERY = 5
#: live playback loop rate, Hz
LIVE_FPS = 30.0
SPEEDS = (0.25, 0.5, 1.0, 2.0)


def static_client_path() -> Path:
    """viser's built static web client (one HTML file) inside the installed package."""
    import viser

    return Path(viser.__file__).resolve().parent / "client" / "build" / "index.html"


@dataclass(frozen=True, eq=False)
class SceneData:
    """What the scene shows, per sample: ``t_s`` (N,), ``q_earth_tibia`` and ``q_tibia_femur`` (N, 4),
    ``angles_deg`` (N, 3); ``q_view_earth`` (4,) the heading removal; meshes and the tibia length."""

    t_s: FloatArray
    q_earth_tibia: FloatArray
    q_tibia_femur: FloatArray
    angles_deg: FloatArray
    q_view_earth: FloatArray
    meshes: dict[str, bones.Mesh]
    tibia_length_m: float
    side: str
    language: str
    cycles_s: list[tuple[int, float, float]]   # (1-based number, start, end) of accepted cycles

    @classmethod
    def from_report_input(cls, ri: ReportInput, *, n_theta: int = 24) -> SceneData:
        if len(ri.t_s) == 0:
            raise ValueError("the task has no samples: nothing to animate")
        for seg in ("femur", "tibia"):
            if seg not in ri.q_earth_segment:
                raise ValueError(f"q_earth_segment has no {seg!r} orientation: the scene needs femur and tibia")
        side = ri.results.get("side") or ri.patient.side or "right"
        if side not in ("right", "left"):
            raise ValueError(f"side must be 'right' or 'left', got {side!r}")
        q_t = quat.normalize(np.asarray(ri.q_earth_segment["tibia"], dtype=float))
        q_f = quat.normalize(np.asarray(ri.q_earth_segment["femur"], dtype=float))
        q_tf = quat.multiply(quat.conjugate(q_t), q_f)
        # constant heading: circular mean of the tibia's anterior-axis azimuth over the task
        x = quat.rotate(q_t, np.array([1.0, 0.0, 0.0]))
        psi = float(np.arctan2(np.nansum(np.sin(np.arctan2(x[:, 1], x[:, 0]))),
                               np.nansum(np.cos(np.arctan2(x[:, 1], x[:, 0])))))
        q_view = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), -psi)
        _, tibia_m = bones.segment_lengths_m(ri.patient.height_m)
        cycles = []
        for k, (start, end, accepted) in enumerate(ri.cycle_bounds_s()):
            if accepted and start is not None and end is not None:
                cycles.append((k + 1, float(start), float(end)))
        return cls(t_s=np.asarray(ri.t_s, dtype=float), q_earth_tibia=q_t, q_tibia_femur=q_tf,
                   angles_deg=np.asarray(ri.angles_deg, dtype=float), q_view_earth=q_view,
                   meshes=bones.leg_meshes(side, ri.patient.height_m, n_theta=n_theta),
                   tibia_length_m=tibia_m, side=side, language=ri.language, cycles_s=cycles)

    def index_at(self, t_s: float) -> int:
        """Sample nearest to ``t_s`` (clipped to the task)."""
        i = int(np.searchsorted(self.t_s, t_s))
        if i >= len(self.t_s):
            return len(self.t_s) - 1
        if i > 0 and t_s - self.t_s[i - 1] < self.t_s[i] - t_s:
            return i - 1
        return i

    def frame_indices(self, rate_hz: float) -> np.ndarray:
        """Sample indices of the whole task resampled at ``rate_hz`` (nearest sample)."""
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        times = np.arange(self.t_s[0], self.t_s[-1] + 0.5 / rate_hz, 1.0 / rate_hz)
        i = np.clip(np.searchsorted(self.t_s, times), 1, len(self.t_s) - 1) if len(self.t_s) > 1 else \
            np.zeros(len(times), dtype=int)
        if len(self.t_s) > 1:
            i = np.where(times - self.t_s[i - 1] < self.t_s[i] - times, i - 1, i)
        return i.astype(int)

    def label_text(self, i: int) -> str:
        lang = self.language
        parts = [f"{i18n.t('scene_label_time', lang)} {i18n.fmt_number(self.t_s[i], 1, lang)} s"]
        for k, name in enumerate(ANGLES):
            parts.append(f"{i18n.t('scene_label_' + name, lang)} {i18n.fmt_number(self.angles_deg[i, k], 1, lang)}°")
        return "   ".join(parts)


@dataclass
class SceneNodes:
    """Handles of the scene nodes (paths in the module docstring)."""

    knee: Any
    tibia: Any
    femur: Any
    label: Any | None
    ground: Any

    def show(self, data: SceneData, i: int) -> None:
        self.tibia.wxyz = data.q_earth_tibia[i]
        self.femur.wxyz = data.q_tibia_femur[i]


def add_nodes(server: Any, data: SceneData, *, with_label: bool) -> SceneNodes:
    """Create the scene nodes on ``server`` (a ``viser.ViserServer``) showing sample 0."""
    rgb = bones.BONE_RGB
    knee = server.scene.add_frame("/knee", show_axes=False, wxyz=data.q_view_earth)
    tibia = server.scene.add_mesh_simple("/knee/tibia", data.meshes["tibia"].vertices,
                                         data.meshes["tibia"].faces, color=rgb, wxyz=data.q_earth_tibia[0])
    femur = server.scene.add_mesh_simple("/knee/tibia/femur", data.meshes["femur"].vertices,
                                         data.meshes["femur"].faces, color=rgb, wxyz=data.q_tibia_femur[0],
                                         position=(0.0, data.tibia_length_m, 0.0))
    label = None
    if with_label:
        label = server.scene.add_label("/knee/angles", data.label_text(0), position=(0.0, 0.0, -0.12),
                                       anchor="top-center")
    ground = server.scene.add_grid("/ground", width=2.0, height=2.0, plane="xy", cell_size=0.1,
                                   section_size=0.5, position=(0.0, 0.0, -0.035))
    # lateral view: the right leg's lateral side is −y after heading removal, the left leg's +y
    lateral = -1.0 if data.side == "right" else 1.0
    server.initial_camera.position = (0.25, 1.1 * lateral, 0.5)  # ~1.1 m away: the leg fills the view
    server.initial_camera.look_at = (0.05, 0.0, 0.42)
    server.initial_camera.up = (0.0, 0.0, 1.0)
    return SceneNodes(knee, tibia, femur, label, ground)


class KneeScene:
    """Live scene with its playback GUI (see :func:`build_scene`)."""

    def __init__(self, server: Any, data: SceneData) -> None:
        self.server = server
        self.data = data
        self.nodes = add_nodes(server, data, with_label=False)
        lang = data.language
        t0, t1 = float(data.t_s[0]), float(data.t_s[-1])
        self._time_s = t0
        self._span_s = (t0, t1)
        self._lock = threading.RLock()
        gui = server.gui
        with gui.add_folder(i18n.t("scene_playback", lang)):
            self.play = gui.add_checkbox(i18n.t("scene_play", lang), initial_value=False)
            self.speed = gui.add_dropdown(i18n.t("scene_speed", lang), options=[f"{s:g}" for s in SPEEDS],
                                          initial_value="1")
            self.time_slider = gui.add_slider(i18n.t("scene_time_s", lang), min=t0, max=max(t1, t0 + 0.01),
                                              step=0.01, initial_value=t0)
            self._cycle_options = {i18n.t("scene_whole_task", lang): (t0, t1)}
            for n, start, end in data.cycles_s:
                text = i18n.t("scene_cycle_option", lang, n=n, start=i18n.fmt_number(start, 1, lang),
                              end=i18n.fmt_number(end, 1, lang))
                self._cycle_options[text] = (start, end)
            self.cycle = gui.add_dropdown(i18n.t("scene_jump_to_cycle", lang), options=list(self._cycle_options))
        with gui.add_folder(i18n.t("scene_angles", lang)):
            self.angle_numbers = [gui.add_number(i18n.t("scene_angle_" + name, lang),
                                                 initial_value=round(float(data.angles_deg[0, k]), 1),
                                                 step=0.1, disabled=True) for k, name in enumerate(ANGLES)]

        @self.time_slider.on_update
        def _(_event: Any) -> None:
            self.show_time(float(self.time_slider.value))

        @self.cycle.on_update
        def _(_event: Any) -> None:
            start, end = self._cycle_options[self.cycle.value]
            with self._lock:
                self._span_s = (start, end)
            self.seek(start)

        self.show_time(t0)

    @property
    def time_s(self) -> float:
        return self._time_s

    def show_time(self, t_s: float) -> int:
        """Pose and angles at ``t_s``; returns the sample shown."""
        i = self.data.index_at(t_s)
        with self._lock, self.server.atomic():
            self._time_s = float(t_s)
            self.nodes.show(self.data, i)
            for k, number in enumerate(self.angle_numbers):
                number.value = round(float(self.data.angles_deg[i, k]), 1)
        return i

    def seek(self, t_s: float) -> None:
        """Move the time slider (and so the scene) to ``t_s``."""
        lo, hi = self.time_slider.min, self.time_slider.max
        t_s = float(np.clip(t_s, lo, hi))
        if abs(self.time_slider.value - t_s) < 1e-9:
            self.show_time(t_s)
        else:
            self.time_slider.value = t_s          # triggers show_time through the slider callback

    def step(self, elapsed_s: float) -> None:
        """Advance playback by ``elapsed_s`` of wall time (× speed) when playing; loops over the span
        of the selected cycle (or the whole task)."""
        if not self.play.value:
            return
        start, end = self._span_s
        t = self._time_s + elapsed_s * float(self.speed.value)
        if t > end or t < start:
            t = start
        self.seek(t)

    def run(self, stop: threading.Event | None = None, fps: float = LIVE_FPS) -> None:
        """Playback loop until ``stop`` is set (or forever; Ctrl-C raises KeyboardInterrupt)."""
        stop = stop or threading.Event()
        period = 1.0 / fps
        last = time.perf_counter()
        while not stop.wait(period):
            now = time.perf_counter()
            self.step(now - last)
            last = now


def build_scene(server: Any, ri: ReportInput) -> KneeScene:
    """Set up the knee scene and its playback GUI on a running ``viser.ViserServer``."""
    return KneeScene(server, SceneData.from_report_input(ri))


@contextlib.contextmanager
def _quiet_server():
    """A throw-away ViserServer on 127.0.0.1 (free port), its start-up banner silenced."""
    import viser

    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        yield server
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def _direct_inserter(server: Any, serializer: Any) -> Any:
    """A fast way to append per-frame messages to ``serializer`` without the live websocket path, or
    None when this viser version does not offer the internals it relies on (viser 1.1.1:
    ``StateSerializer._insert_message`` and the message classes in ``viser._messages``).

    Per kind of message (orientation, label text), the first one goes through viser's own
    ``_insert_message`` (``as_serializable_dict``: ~80 µs a message, most of a recording's cost); when
    the dict it recorded equals, key order included, the plain dict built here, the later ones of that
    kind are appended to the recording as such plain dicts (~1 µs), else they all take viser's path."""
    try:
        from viser import _messages
    except ImportError:                                           # pragma: no cover - other viser versions
        return None
    insert = getattr(serializer, "_insert_message", None)
    orientation = getattr(_messages, "SetOrientationMessage", None)
    node_update = getattr(_messages, "SceneNodeUpdateMessage", None)
    if insert is None or orientation is None or node_update is None:  # pragma: no cover
        return None
    owner = getattr(server.scene, "_owner_id", "")
    recorded = getattr(serializer, "_messages", None)
    plain_ok: dict[str, bool] = {}

    def emit(name: str, wxyz: FloatArray | None = None, text: str | None = None) -> None:
        if text is not None:
            kind, plain = "text", {"name": name, "updates": {"text": text}, "owner": owner,
                                   "type": "SceneNodeUpdateMessage"}
        else:
            kind, plain = "wxyz", {"name": name, "wxyz": (float(wxyz[0]), float(wxyz[1]), float(wxyz[2]),
                                                          float(wxyz[3])), "owner": owner,
                                   "type": "SetOrientationMessage"}
        if plain_ok.get(kind):
            recorded.append((serializer._time, plain))
            return
        message = node_update(name, {"text": text}) if text is not None else orientation(name, plain["wxyz"])
        message.owner = owner
        before = len(recorded) if isinstance(recorded, list) else -1
        insert(message)
        if kind not in plain_ok:
            plain_ok[kind] = (before >= 0 and len(recorded) == before + 1 and isinstance(getattr(serializer, "_time",
                              None), float) and list(recorded[-1][1].items()) == list(plain.items()))

    return emit


def _record(server: Any, data: SceneData, rate_hz: float, label_every: int, *, fast: bool = True) -> Any:
    """Add the nodes, then record the task's frames on a scene serialiser; returns the serialiser.

    fast=True appends the per-frame messages straight to the serialiser (same messages as the public
    handle setters produce, ~3× quicker: no websocket queue, no per-update change check); fast=False, or
    a viser without those internals, uses the public handles inside ``server.atomic()``."""
    nodes = add_nodes(server, data, with_label=True)
    idx = data.frame_indices(rate_hz)
    nodes.show(data, int(idx[0]))
    serializer = server.get_scene_serializer()
    emit = _direct_inserter(server, serializer) if fast else None
    dt = 1.0 / rate_hz
    last_text = data.label_text(int(idx[0]))
    # what the public setters skip (np.allclose to the previous value), skipped: decided for all frames at once
    q_t_all, q_tf_all = data.q_earth_tibia[idx], data.q_tibia_femur[idx]
    moved_t = np.concatenate([[False], ~np.isclose(q_t_all[1:], q_t_all[:-1]).all(axis=1)])
    moved_tf = np.concatenate([[False], ~np.isclose(q_tf_all[1:], q_tf_all[:-1]).all(axis=1)])
    for k, i in enumerate(idx):
        i = int(i)
        if k:
            serializer.insert_sleep(dt)
        text = data.label_text(i) if k % label_every == 0 else last_text
        if emit is None:
            with server.atomic():
                nodes.show(data, i)
                if text != last_text:
                    nodes.label.text = text
        else:
            if moved_t[k]:
                emit(nodes.tibia.name, q_t_all[k])
            if moved_tf[k]:
                emit(nodes.femur.name, q_tf_all[k])
            if text != last_text:
                emit(nodes.label.name, text=text)
        last_text = text
    serializer.insert_sleep(dt)
    return serializer


def scene_bytes(ri: ReportInput, *, rate_hz: float = SCENE_RATE_HZ, label_every: int = LABEL_EVERY) -> bytes:
    """The recorded animation as ``.viser`` bytes (see module docstring)."""
    if label_every < 1:
        raise ValueError(f"label_every must be >= 1, got {label_every}")
    data = SceneData.from_report_input(ri)
    with _quiet_server() as server:
        return _record(server, data, rate_hz, label_every).serialize()


def export_scene(ri: ReportInput, path: str | os.PathLike, *, rate_hz: float = SCENE_RATE_HZ,
                 label_every: int = LABEL_EVERY) -> Path:
    """Write the recorded animation to ``path`` (conventionally ``scene.viser``); returns the path."""
    out = Path(path)
    out.write_bytes(scene_bytes(ri, rate_hz=rate_hz, label_every=label_every))
    return out


def scene_html(ri: ReportInput, *, rate_hz: float = SCENE_RATE_HZ, dark_mode: bool = False) -> str:
    """One offline HTML file: viser's static client with the recording embedded (viser ``as_html``)."""
    data = SceneData.from_report_input(ri)
    with _quiet_server() as server:
        return _record(server, data, rate_hz, LABEL_EVERY).as_html(dark_mode=dark_mode)


#: the largest decompressed ``.viser`` payload read back, bytes.  The file states its own size, and zstd ignores an
#: output limit when the frame header states its content size too (a 12.8 KB file can ask for 400 MB), so the
#: payload is read through a streaming decompressor that stops at this many bytes.  A 30-minute task's recording
#: decompresses to a few MB.
MAX_INNER_BYTES = 64 * 2**20


def inner_bytes(raw: bytes, limit: int = MAX_INNER_BYTES) -> bytearray:
    """A ``.viser`` recording's decompressed inner payload (module docstring's layout), never more than ``limit``
    bytes decompressed (:data:`MAX_INNER_BYTES`): ``ValueError`` for a payload that is, or says it is, larger, or
    that does not decompress to the size it states."""
    import zstandard

    if len(raw) < 16:
        raise ValueError("not a .viser recording: too short")
    inner_size = int.from_bytes(raw[:8], "little")
    if inner_size > limit:
        raise ValueError(f"the .viser recording states {inner_size} bytes decompressed, more than {limit}")
    inner, total = bytearray(inner_size), 0   # filled in place: no second copy of the payload
    view = memoryview(inner)
    try:
        with zstandard.ZstdDecompressor().stream_reader(raw[8:]) as reader:
            while total < inner_size:
                got = reader.readinto(view[total:])
                if not got:
                    break
                total += got
            beyond = len(reader.read(1))
    except zstandard.ZstdError as exc:
        raise ValueError(f"corrupt .viser recording: {exc}") from exc
    finally:
        view.release()
    if total != inner_size or beyond:
        raise ValueError(f"corrupt .viser recording: {'more than ' if beyond else ''}{total} bytes "
                         f"decompressed, {inner_size} announced")
    return inner


def inner_payload(raw: bytes) -> tuple[bytearray, dict[str, Any]]:
    """A ``.viser`` recording's decompressed inner payload (:func:`inner_bytes`) and its decoded msgpack part
    (module docstring's layout): ``(inner, {"durationSeconds", "messages", "viserVersion", "binaryBufferLengths"})``."""
    import msgspec.msgpack

    inner = inner_bytes(raw)
    n = int.from_bytes(inner[:8], "little")
    return inner, msgspec.msgpack.decode(memoryview(inner)[8:8 + n])


def read_scene(source: str | os.PathLike | bytes) -> dict[str, Any]:
    """Decode a ``.viser`` recording: ``{"durationSeconds", "messages": [(t_s, {"type", "name", ...})],
    "viserVersion", "binaryBufferLengths"}`` (binary arrays left as placeholders; :mod:`reports.scene_still`
    reads them)."""
    raw = source if isinstance(source, bytes) else Path(source).read_bytes()
    return inner_payload(raw)[1]
