"""Data model of the ingestion layer: streams as read, recordings, aligned recordings, the session.

Every array is in the project's units (DESIGN §3): acc m/s² (specific force), gyr rad/s, mag µT,
time in seconds.  Conversion from file units happens once, in the readers (:mod:`.units`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Segment names used everywhere in the pipeline.
SEGMENTS = ("thigh", "shank")
#: Recording roles of one session (seed 004 §8.4): magnetometer calibration, standing, lying, task.
ROLES = ("mag_calibration", "standing", "lying", "task")
#: Stream kinds and their project unit.
KINDS = {"acc": "m/s²", "gyr": "rad/s", "mag": "µT"}


class IngestionError(ValueError):
    """A file or folder cannot be ingested.  The message names the file and says what to do.

    ``IngestionError(code, **params)`` with ``code`` a key of :data:`.messages.CATALOGUE`: ``str(exc)`` is the
    English text, :meth:`message` renders it in ``"es"``, ``"en"`` or ``"pt"``; ``code`` and ``params`` stay on
    the exception for the API (``{"code": exc.code, "params": exc.params}``).  ``IngestionError(text)`` with
    any other string (callers outside this package) keeps that text in every language, ``code == "text"``.
    """

    def __init__(self, code: str, /, **params: Any) -> None:
        from app.pipeline.ingestion.messages import CATALOGUE, render

        if code in CATALOGUE:
            self.code, self.params = code, {k: _plain(v) for k, v in params.items()}
            text = render(code, self.params, "en")
        else:
            self.code, self.params, text = "text", {"text": code}, code
        super().__init__(text)

    def message(self, lang: str = "en") -> str:
        """The message in ``lang`` (es/en/pt; an unknown language gives English)."""
        from app.pipeline.ingestion.messages import render

        return str(self) if self.code == "text" else render(self.code, self.params, lang)

    def __reduce__(self):  # pickle (job engines): rebuilt from code and params, not from the English text
        return (_rebuild_error, (self.code, dict(self.params), str(self)))


def rows_all(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``mask.all(axis=1)`` of a narrow ``(n, k)`` bool array, one column at a time: numpy's reduction along a
    short last axis costs ~15 ns a row (0.65 ms for 36 000 × 3), the columns ~1 ns (0.05 ms)."""
    out = np.ones(len(mask), dtype=bool)
    for k in range(mask.shape[1]):
        out &= mask[:, k]
    return out


def rows_any(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``mask.any(axis=1)`` of a narrow ``(n, k)`` bool array, one column at a time (:func:`rows_all`)."""
    out = np.zeros(len(mask), dtype=bool)
    for k in range(mask.shape[1]):
        out |= mask[:, k]
    return out


def _plain(value: Any) -> Any:
    """A message parameter as JSON can carry it: paths as text, numpy scalars as Python numbers."""
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, np.generic):
        return value.item()
    return value


def _rebuild_error(code: str, params: dict, text: str) -> "IngestionError":
    return IngestionError(code, **params) if code != "text" else IngestionError(text)


class Note(str):
    """A note for the user (an English sentence, usable wherever a ``str`` is) that also carries ``params``:
    its values by name (``{"variant": "stream_cut_after", "stream": "gyr", "seconds": 1.53}``, plus
    ``segment``/``role`` once the session prefixes it), so the pipeline's ``ingestion_note`` warning can be
    translated from data (``reports/translations_warnings.json``, ``warning.ingestion_note.<variant>``).

    A ``str`` subclass so ``Session.notes`` stays a tuple of sentences for every reader of it; ``params``
    is a read-only copy.  Notes without a translation (file ignored) stay plain ``str``.
    """

    params: Mapping[str, Any]

    def __new__(cls, text: str, params: Mapping[str, Any] | None = None) -> "Note":
        note = super().__new__(cls, text)
        note.params = MappingProxyType({k: _plain(v) for k, v in (params or {}).items()})
        return note

    @classmethod
    def of(cls, variant: str, **params: Any) -> "Note":
        """The note ``note.<variant>`` of :data:`.messages.CATALOGUE`, its English text from the catalogue."""
        from app.pipeline.ingestion.messages import render

        params = {k: _plain(v) for k, v in params.items()}
        return cls(render(f"note.{variant}", params, "en"), {"variant": variant, **params})

    @property
    def code(self) -> str | None:
        """``note.<variant>`` when the catalogue has it (see :meth:`message`), else ``None``."""
        from app.pipeline.ingestion.messages import CATALOGUE

        code = f"note.{self.params.get('variant')}"
        return code if code in CATALOGUE else None

    def message(self, lang: str = "en") -> str:
        """The note in ``lang`` (es/en/pt), prefixed with its segment and role when it has them."""
        from app.pipeline.ingestion.messages import render, render_prefix

        if self.code is None:
            return str(self)
        text = render(self.code, self.params, lang)
        if "segment" in self.params and "role" in self.params:
            text = f"{render_prefix(self.params['segment'], self.params['role'], lang)}: {text}"
        return text

    def __reduce__(self):  # pickle/deepcopy: a mappingproxy cannot be pickled, its dict can
        return (type(self), (str(self), dict(self.params)))

    def prefixed(self, segment: str, role: str) -> "Note":
        """``"<segment> <role>: <note>"`` with ``segment`` and ``role`` added to the params."""
        return Note(f"{segment} {role}: {self}", {**self.params, "segment": segment, "role": role})


@dataclass(frozen=True)
class Recognition:
    """How a value (segment, role, side, ...) was found.

    value : the canonical value (``"thigh"``, ``"task"``, ``"right"``, ``0.34``...).
    method : ``"file name"``, ``"MetaBase label"``, ``"session.json"``, ``"default"`` or ``"argument"``.
    evidence : the word or entry that decided it (``"muslo"``, ``"-H suffix"``, ``"recordings[2].segment"``).
    """

    value: Any
    method: str
    evidence: str = ""

    def describe(self) -> str:
        return f"{self.value} (from {self.method}{': ' + repr(self.evidence) if self.evidence else ''})"


@dataclass(frozen=True, eq=False)
class Stream:
    """One sensor stream as read from a file, already in project units.

    kind : ``"acc"``, ``"gyr"`` or ``"mag"``.
    t_s : (n,) time stamps, s, strictly increasing.  Absolute (Unix epoch seconds) when the file has
        epoch stamps (MetaBase); otherwise seconds from the file's own start (``time_base="elapsed"``).
    values : (n, 3) float64 in m/s², rad/s or µT; rows may hold NaN (missing samples).
    declared_unit : the unit the file declared (``"g"``, ``"deg/s"``, ``"T"``...).
    file : the source file.   nominal_fs_hz : the rate the file name declares, if any.
    time_base : ``"epoch"`` or ``"elapsed"``.
    notes : :class:`Note` s from the reader (rows dropped, time base rebuilt, ``;`` separator...).
    mag_unit : for ``kind="mag"``: ``"µT"`` (every format with a field unit) or ``"normalised"`` (Xsens, a
        generic ``(normalised)`` column: the vendor's calibrated field divided by its local strength, norm ≈ 1,
        no µT scale).  Normalised values are kept as the file gives them (norm ≈ 1), never scaled to µT, so
        the figure-eight fit must not assume µT (nor be needed: the vendor calibrated them).
    field_ut : the local field strength the file (or ``session.json``) declares for a normalised
        magnetometer, µT, else ``None``; ``values * field_ut`` would be µT.
    """

    kind: str
    t_s: FloatArray
    values: FloatArray
    declared_unit: str
    file: Path
    nominal_fs_hz: float | None = None
    time_base: str = "epoch"
    notes: tuple = ()
    mag_unit: str = "µT"
    field_ut: float | None = None

    @property
    def fs_hz(self) -> float:
        """Rate measured from the stamps, Hz: 1 / mean period, periods longer than 1.5 median ones (gaps)
        left out, so millisecond rounding of the stamps does not hide a 1 % clock drift."""
        d = np.diff(self.t_s)
        return float(1.0 / np.mean(d[d <= 1.5 * np.median(d)]))

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])


@dataclass(frozen=True, eq=False)
class RawRecording:
    """One sensor × one role, three streams as read (each with its own stamps), not yet aligned.

    fmt : ``"metabase"``, ``"thesis-xlsx"`` or ``"generic-csv"``.
    segment, role : :class:`Recognition` of the segment (thigh/shank) and role.
    sensor_id : MAC address (MetaBase) or ``None``.   label : the recording label / file stem.
    extras : other facts found in the names (patient id, date, trial number, side, step height),
        each a :class:`Recognition`.
    notes : human-readable remarks from the reader (sheet chosen, ...).
    """

    acc: Stream
    gyr: Stream
    mag: Stream
    fmt: str
    segment: Recognition | None
    role: Recognition | None
    label: str
    sensor_id: str | None = None
    extras: dict[str, Recognition] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @property
    def files(self) -> tuple[Path, ...]:
        return tuple(dict.fromkeys((self.acc.file, self.gyr.file, self.mag.file)))

    @property
    def streams(self) -> tuple[Stream, Stream, Stream]:
        return (self.acc, self.gyr, self.mag)


@dataclass(frozen=True, eq=False)
class AlignedRecording:
    """One sensor × one role with acc, gyr and mag on one uniform grid.

    t_s : (N,) grid, s, ``t_s[k] = k / fs_hz`` (starts at 0).
    acc, gyr, mag : (N, 3) in m/s², rad/s, µT, linearly interpolated on each stream's own stamps;
        rows inside a gap of a stream (> 2.5 of its periods without a valid sample) are NaN.
    fs_hz : grid rate, Hz.
    t0_s : the grid's first instant on the files' time base (epoch s for MetaBase, else elapsed s).
    time_base : ``"epoch"`` or ``"elapsed"``.
    segment, role : canonical names (``"thigh"``, ``"task"``...).
    source : where the data came from: ``files``, ``format``, ``segment`` / ``role``
        (:meth:`Recognition.describe` strings), ``sensor_id``, ``label``.
    flags : facts about the alignment: ``stream_fs_hz`` (measured rates), ``trimmed_s`` (per stream,
        seconds cut at start/end to reach the common span), ``nan_rows`` (per stream, rows NaN on
        the grid), ``notes`` (list of sentences worth showing a user).
    """

    t_s: FloatArray
    acc: FloatArray
    gyr: FloatArray
    mag: FloatArray
    fs_hz: float
    t0_s: float
    time_base: str
    segment: str
    role: str
    source: dict[str, Any]
    flags: dict[str, Any]

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def duration_s(self) -> float:
        return float(len(self.t_s) / self.fs_hz)

    @property
    def mag_normalised(self) -> bool:
        """True when ``mag`` is in normalised units (norm ≈ 1, no µT scale; ``flags["mag_field_ut"]`` the
        declared field strength or ``None``): the figure-eight fit must not assume µT."""
        return self.flags.get("mag_unit") == "normalised"


@dataclass(frozen=True)
class SessionMetadata:
    """Facts about the session found in names or the manifest, each with how it was found.

    patient_id, side (``"right"``/``"left"``), step_height_m, date (ISO ``YYYY-MM-DD``), trial:
    :class:`Recognition` or ``None`` when nothing said it.
    """

    patient_id: Recognition | None = None
    side: Recognition | None = None
    step_height_m: Recognition | None = None
    date: Recognition | None = None
    trial: Recognition | None = None

    def value(self, name: str) -> Any:
        r = getattr(self, name)
        return None if r is None else r.value


@dataclass(frozen=True, eq=False)
class Session:
    """One session folder: 2 sensors × 4 recordings, each aligned, plus the task pair on one grid.

    folder : the session folder.   fmt : the input format(s) used.
    recordings : ``{(segment, role): AlignedRecording}``, each on its own grid.
    raw : ``{(segment, role): RawRecording}`` (the streams as read, own stamps).
    task : ``(thigh, shank)`` task recordings resampled onto one common grid.
    metadata : :class:`SessionMetadata`.   manifest : path of ``session.json`` if one was used.
    manifest_data : its parsed, checked content (``{}`` without one), read once here.
    notes : sentences worth showing a user (sheet chosen, streams trimmed, default step height...); for
        the task, those of ``task`` (trimmed to the pair's span, clock drift between the sensors).
    splits : :class:`.split.Split` per sensor whose one continuous recording was split into the protocol's parts.
    patient_side : for a knee of a two-knee session (:func:`.session.load_knees`), the patient's side (the involved
        knee) that ``session.json`` names, kept apart from ``metadata.side`` (this knee's own); None elsewhere.
    """

    folder: Path
    recordings: dict[tuple[str, str], AlignedRecording]
    raw: dict[tuple[str, str], RawRecording]
    task: tuple[AlignedRecording, AlignedRecording]
    metadata: SessionMetadata
    manifest: Path | None = None
    notes: tuple[str, ...] = ()
    manifest_data: Mapping[str, Any] = field(default_factory=dict)
    splits: tuple = ()
    patient_side: str | None = None

    def recording(self, segment: str, role: str) -> AlignedRecording:
        """The aligned recording of ``segment`` (thigh/shank) in ``role`` (see :data:`ROLES`)."""
        key = (segment, role)
        if key not in self.recordings:
            raise KeyError(f"no {role} recording of the {segment} in {self.folder}; have {sorted(self.recordings)}")
        return self.recordings[key]

    def task_pair(self) -> tuple[AlignedRecording, AlignedRecording]:
        """``(thigh, shank)`` task recordings on one common grid (same ``t_s``, same length)."""
        return self.task
