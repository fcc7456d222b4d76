"""One session folder → :class:`Session`: discover files, recognise segment and role, read, check, align.

Discovery (without ``session.json`` ``recordings``): MetaBase files are grouped by (label, MAC) into one
recording of three streams; every other ``.xlsx`` is a thesis workbook and every other ``.csv`` a generic
CSV, one recording each.  Role and segment come from the label / file stem (:mod:`.labels`), a MetaBase
sensor's segment may also come from the manifest's ``sensors`` map (MAC → segment).

``session.json`` (every key optional)::

    {
      "patient_id": "ML1", "side": "right", "step_height_m": 0.17, "date": "2023-03-13",
      "sensors": {"EB942CED9472": "thigh", "C3A1B2D4E5F6": "shank"},
      "paired_session": "../left-knee",
      "recordings": [
        {"files": ["step-muslo-ML1-13032023-1.xlsx"], "segment": "thigh", "role": "task", "sheet": "Hoja1"},
        {"files": ["a_MetaWear_..._Accelerometer_100.000Hz_1.5.1.csv", "..._Gyroscope_...", "..._Magnetometer_..."],
         "segment": "pierna", "role": "step"}
      ]
    }

A recording of the whole protocol per sensor (role ``continuous``, or no role and one recording per sensor) is
split into figure-eight, standing, supine and task (:mod:`.split`); ``Session.splits`` says where.

``recordings`` (when present) lists exactly the files to use; ``segment`` / ``role`` (and ``side``, for a folder of
both knees: :func:`load_knees`) accept the same words as the file names in any of the three languages, and fall
back to the names when absent.  The manifest wins
over names; every :class:`Recognition` says which one decided.

Swapped segments (thigh sensor labelled shank) cannot be seen from the files; the pipeline checks it on
the signals.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import replace
from pathlib import Path
from typing import Any, Sequence

from app.pipeline.ingestion.align import align_pair, align_recording, check_rates
from app.pipeline.ingestion.excel import OneWorkbook, read_thesis_xlsx
from app.pipeline.ingestion.generic import read_generic_csv
from app.pipeline.ingestion.labels import (AmbiguousLabel, LOW_STEP_M, parse_thesis_name, recognise_role, recognise_segment, recognise_side,
                                  recognise_step_height)
from app.pipeline.ingestion.metabase import (group_metabase_files, parse_file_name, read_metabase_csv, settle_local_time,
                                            start_time)
from app.pipeline.ingestion.model import (ROLES, SEGMENTS, IngestionError, Note, RawRecording, Recognition, Session,
                                 SessionMetadata)
from app.pipeline.ingestion.opal import list_sensors, read_opal
from app.pipeline.ingestion.split import CONTINUOUS, knee_split, left_unsplit, split_session
from app.pipeline.ingestion.phyphox import looks_like_phyphox, read_phyphox
from app.pipeline.ingestion.sensorlogger import looks_like_sensorlogger, read_sensorlogger
from app.pipeline.ingestion.shimmer import looks_like_shimmer, read_shimmer
from app.pipeline.ingestion.units import check_gyro_unit
from app.pipeline.ingestion.xsens import looks_like_xsens, read_xsens

MANIFEST = "session.json"
#: keys of session.json; from ``name`` on they are only shown in the reports' patient block and identity line,
#: as typed (``identifier_system`` is the URI of ``patient_id``'s namespace, ``birth_date`` ISO, ``sex`` one of
#: male/female/other/unknown, ``clinic`` the clinic's name)
_MANIFEST_KEYS = {"patient_id", "side", "step_height_m", "date", "sensors", "recordings", "mag_field_ut", "split",
                  "paired_session", "name", "professional", "weight_kg", "height_m", "observations",
                  "identifier_system", "birth_date", "sex", "clinic"}
_ENTRY_KEYS = {"files", "segment", "role", "sheet", "sensor", "side"}
#: the type each key must have (a wrong one is refused by _read_manifest, so later code can rely on it)
_MANIFEST_TYPES = {"patient_id": (str, int), "side": str, "step_height_m": (int, float), "date": str,
                   "mag_field_ut": (int, float), "split": dict, "paired_session": str,
                   "sensors": dict, "recordings": list, "name": str, "professional": str,
                   "weight_kg": (int, float, type(None)), "height_m": (int, float, type(None)), "observations": str,
                   "identifier_system": str, "birth_date": str, "sex": str, "clinic": str}
_TYPE_NAMES = {str: "a string", int: "an integer", float: "a number", dict: "an object", list: "a list",
               type(None): "null"}


def read_recording(files: Sequence[str | os.PathLike], *, sheet: str | None = None, hint: Any = "",
                   settle: bool = True, sensor: str | None = None) -> RawRecording:
    """Read one recording (3 MetaBase files, 1 thesis .xlsx, or 1 generic .csv), segment/role from its name.

    ``hint`` ends the message when a MetaBase stream file is missing (the files discovery left out: a stream
    renamed out of the MetaBase pattern is one of them).  ``settle=False`` leaves MetaBase stamps rebuilt
    on local time (:func:`.metabase.settle_local_time`) for the session to put on UTC with other recordings.
    ``sensor`` picks one sensor of an APDM ``.h5`` file holding several (its segment from the sensor's label).

    ``extras`` gains, when the files say them: ``started`` (ISO local date-time of the recording's start,
    from the MetaBase name), ``device`` (the sensor's user-chosen name), ``firmware``."""
    facts: dict[str, Recognition] = {}
    if not files:
        raise IngestionError("recording.no_files")
    paths = [Path(f) for f in files]
    for p in paths:
        if not p.is_file():
            raise IngestionError("file.not_found", file=p)
    notes: tuple[str, ...] = ()
    sensor_id = None
    book = OneWorkbook()   # the .xlsx files, one open at a time, shared by the phyphox sniff and the reader
    try:
        if all(parse_file_name(p) for p in paths):
            groups = group_metabase_files(paths)
            if len(groups) != 1:
                raise IngestionError("metabase.several_recordings", file=paths[0], count=len(groups),
                                     labels=", ".join(f"{l} ({t})" for l, _, t in groups) or "-")
            (label, sensor_id, started), kinds = next(iter(groups.items()))
            missing = [k for k in ("acc", "gyr", "mag") if k not in kinds]
            if missing:
                names = {"acc": "Accelerometer", "gyr": "Gyroscope", "mag": "Magnetometer"}
                raise IngestionError("metabase.stream_missing", file=paths[0].parent, label=label, sensor=sensor_id,
                                     streams=" / ".join(names[k] for k in missing), hint=hint)
            streams = [read_metabase_csv(kinds[k], k) for k in ("acc", "gyr", "mag")]
            acc, gyr, mag = settle_local_time(streams, final=settle)
            fmt = "metabase"
            method = "MetaBase label"
            name = parse_file_name(kinds["acc"])
            start = start_time(name)
            facts["started"] = Recognition(start.isoformat(timespec="seconds"), "MetaBase file name",
                                           name["datetime"])
            facts["device"] = Recognition(name["device"], "MetaBase file name", name["device"])
            if name["firmware"]:
                facts["firmware"] = Recognition(name["firmware"], "MetaBase file name", name["firmware"])
        elif all(p.suffix.lower() in (".csv", ".txt", ".zip", ".xlsx") for p in paths) \
                and all(looks_like_phyphox(p, book(p)) for p in paths):
            acc, gyr, mag, sensor_id = read_phyphox(paths, book)
            stems = [p.stem for p in paths]
            label = os.path.commonprefix(stems).strip(" _-") if len(stems) > 1 else stems[0]
            label, fmt, method = label or stems[0], "phyphox", "file name"
        elif len(paths) == 1 and paths[0].suffix.lower() == ".xlsx":
            acc, gyr, mag, note = read_thesis_xlsx(paths[0], sheet, book(paths[0]))
            rest = {k: v for k, v in note.params.items() if k != "variant"}
            notes = (Note.of("file_sheet_chosen_of" if "sheets" in rest else "file_sheet_chosen", file=paths[0].name,
                             **rest),)
            label, fmt, method = paths[0].stem, "thesis-xlsx", "file name"
        elif len(paths) == 1 and paths[0].suffix.lower() in (".h5", ".hdf5"):
            acc, gyr, mag, sensor_id, sensor_label = read_opal(paths[0], sensor)
            label, fmt, method = f"{paths[0].stem} {sensor_label}".strip(), "apdm-opal", "file name"
        elif len(paths) == 1 and paths[0].suffix.lower() == ".zip":
            acc, gyr, mag, sensor_id = read_sensorlogger(paths[0])
            label, fmt, method = paths[0].stem, "sensor-logger", "file name"
        elif len(paths) == 1 and paths[0].suffix.lower() in (".csv", ".txt"):
            fmt = sniff(paths[0]) or "generic-csv"
            if fmt == "xsens":
                acc, gyr, mag, sensor_id = read_xsens(paths[0])
            elif fmt == "shimmer":
                acc, gyr, mag, sensor_id = read_shimmer(paths[0])
            else:
                acc, gyr, mag = read_generic_csv(paths[0])
            label, method = paths[0].stem, "file name"
        else:
            raise IngestionError("recording.bad_file_set", file=paths[0], files=", ".join(p.name for p in paths))
    finally:
        book.close()
    found = {}
    for name, finder in (("role", recognise_role), ("segment", recognise_segment), ("side", recognise_side),
                         ("step", recognise_step_height)):
        try:
            found[name] = finder(label, method)
        except AmbiguousLabel as exc:   # ambiguous: left to session.json, reported if nothing decides
            found[name] = None
            notes += (Note(f"{paths[0].name}: {exc}", {"file": paths[0].name, "ambiguous": exc.fragment()}),)
    role, segment, side, step = found["role"], found["segment"], found["side"], found["step"]
    extras = {**facts, **(parse_thesis_name(label) or {})}
    if side:
        extras["side"] = side
    if step:
        extras["step_height_m"] = step
    if "patient_id" in extras and extras["patient_id"].method != method:
        extras["patient_id"] = Recognition(extras["patient_id"].value, method, "ID field")
    notes += tuple(n for st in (acc, gyr, mag) for n in st.notes)
    return RawRecording(acc=acc, gyr=gyr, mag=mag, fmt=fmt, segment=segment, role=role, label=label,
                        sensor_id=sensor_id, extras=extras, notes=tuple(dict.fromkeys(notes)))


#: the largest ``session.json`` (kB) and its deepest nesting: a real one nests 4 deep (object → recordings →
#: entry → files) and takes a few kB, observations included; more is refused before it is parsed (issue 16,
#: finding 5: a deeply nested one made ``json`` raise RecursionError, a 500 on every read of its session)
MAX_MANIFEST_KB = 256
MAX_MANIFEST_DEPTH = 8
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_JSON_BRACKET = re.compile(r"[\[\]{}]")


def json_depth(text: str) -> int:
    """The deepest nesting of arrays and objects in JSON ``text`` (strings skipped; no recursion, so any depth
    is measured): ``{"a": [1]}`` → 2."""
    depth = deepest = 0
    for m in _JSON_BRACKET.finditer(_JSON_STRING.sub("", text)):
        if m.group() in "[{":
            depth += 1
            deepest = max(deepest, depth)
        else:
            depth -= 1
    return deepest


def check_manifest_size(text: str, file: Any, size_bytes: int | None = None) -> None:
    """Refuse (:class:`IngestionError`) a manifest larger than :data:`MAX_MANIFEST_KB` or nested deeper than
    :data:`MAX_MANIFEST_DEPTH` (the upload route calls it on the uploaded bytes too)."""
    size = len(text.encode("utf-8")) if size_bytes is None else size_bytes
    if size > MAX_MANIFEST_KB * 1024:
        raise IngestionError("manifest.too_large", file=file, size_kb=-(-size // 1024), limit_kb=MAX_MANIFEST_KB)
    if json_depth(text) > MAX_MANIFEST_DEPTH:
        raise IngestionError("manifest.too_deep", file=file, limit=MAX_MANIFEST_DEPTH)


def parse_manifest(text: str, file: Any) -> Any:
    """``json.loads(text)`` of a ``session.json`` within the caps of :func:`check_manifest_size`; json's own
    RecursionError (a depth the count missed) is the same refusal.  ``json.JSONDecodeError`` passes through."""
    check_manifest_size(text, file)
    try:
        return json.loads(text)
    except RecursionError:
        raise IngestionError("manifest.too_deep", file=file, limit=MAX_MANIFEST_DEPTH) from None


def _read_manifest(path: Path) -> dict[str, Any]:
    """``session.json`` parsed and checked: size and depth, keys, their types, and every listed file once,
    inside the folder."""
    try:
        size = path.stat().st_size
        if size > MAX_MANIFEST_KB * 1024:  # refused before it is read
            raise IngestionError("manifest.too_large", file=path, size_kb=-(-size // 1024), limit_kb=MAX_MANIFEST_KB)
        data = parse_manifest(path.read_text(encoding="utf-8-sig"), path)
    except UnicodeDecodeError:
        raise IngestionError("manifest.not_utf8", file=path) from None
    except json.JSONDecodeError as exc:
        raise IngestionError("manifest.invalid_json", file=path, line=exc.lineno, col=exc.colno,
                             reason=exc.msg) from None
    if not isinstance(data, dict):
        raise IngestionError("manifest.not_object", file=path, keys=", ".join(sorted(_MANIFEST_KEYS)))
    unknown = set(data) - _MANIFEST_KEYS
    if unknown:
        raise IngestionError("manifest.unknown_keys", file=path, unknown=str(sorted(unknown)),
                             keys=", ".join(sorted(_MANIFEST_KEYS)))
    for key, types in _MANIFEST_TYPES.items():
        types = types if isinstance(types, tuple) else (types,)
        if key in data and (not isinstance(data[key], types) or isinstance(data[key], bool)):
            raise IngestionError("manifest.wrong_type", file=path, key=key, value=repr(data[key])[:60],
                                 expected=" | ".join(_TYPE_NAMES[t] for t in types))
    for mac, segment in data.get("sensors", {}).items():
        if not isinstance(segment, str):
            raise IngestionError("manifest.sensor_segment_type", file=path, mac=str(mac), value=repr(segment)[:60])
    if "recordings" in data and not data["recordings"]:
        raise IngestionError("manifest.recordings_empty", file=path)
    root = path.parent.resolve()
    listed: dict[Path, int] = {}
    for i, e in enumerate(data.get("recordings", [])):
        if not isinstance(e, dict) or not isinstance(e.get("files"), list) or not e["files"] or set(e) - _ENTRY_KEYS \
                or not all(isinstance(e.get(k, ""), str) for k in ("segment", "role", "side")) \
                or not isinstance(e.get("sheet", ""), (str, type(None))) or not isinstance(e.get("sensor", ""), str):
            raise IngestionError("manifest.bad_entry", file=path, index=i)
        for f in e["files"]:
            if not isinstance(f, str) or not f or not (root / f).resolve().is_relative_to(root) \
                    or (root / f).resolve() == root:
                raise IngestionError("manifest.file_outside", file=path, index=i, name=repr(f)[:80])
            where = (root / f).resolve()
            if where in listed:
                raise IngestionError("manifest.file_twice", file=path, name=f, first=listed[where], second=i)
            listed[where] = i
    return data


def _manifest_word(path: Path, where: str, text: str, kind: str) -> Recognition:
    finder = recognise_segment if kind == "segment" else recognise_role
    try:
        r = finder(str(text), "session.json")
    except ValueError as exc:
        r, _ = None, exc
    if r is None:
        if text in (SEGMENTS if kind == "segment" else ROLES + (CONTINUOUS,)):
            return Recognition(text, "session.json", where)
        raise IngestionError("manifest.unknown_segment" if kind == "segment" else "manifest.unknown_role",
                             file=path, where=where, value=str(text)[:60],
                             allowed=", ".join(SEGMENTS if kind == "segment" else ROLES + (CONTINUOUS,)))
    return Recognition(r.value, "session.json", where)


def sniff(path: Path) -> str | None:
    """The format of a non-MetaBase ``.csv`` / ``.txt`` from its first 8 kB: ``"xsens"`` (MT Manager export),
    ``"shimmer"`` (Consensys), ``"phyphox"``, ``"generic-csv"`` (a header naming ``acc_x``), or ``None``."""
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            head = fh.read(8192)
    except OSError:
        return None
    if looks_like_xsens(head):
        return "xsens"
    if looks_like_shimmer(head):
        return "shimmer"
    if looks_like_phyphox(path):
        return "phyphox"
    first = head.split("\n", 1)[0].lower()
    return "generic-csv" if path.suffix.lower() == ".csv" and "acc_x" in first else None


#: why _discover leaves a .csv out (shown in notes, and in the error when a recording or stream is then missing)
_IGNORED_CSV = "neither a MetaBase export nor a generic CSV with acc_x..."


def _discover(folder: Path) -> tuple[list[list[Path]], list[str]]:
    """The folder's recordings (file groups) and the ``.csv`` files left out (their names)."""
    files = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith(("~$", ".")))
    meta = [p for p in files if p.suffix.lower() == ".csv" and parse_file_name(p)]
    groups = [sorted(g.values()) for g in group_metabase_files(meta).values()]
    singles, ignored = [], []
    for p in files:
        suffix = p.suffix.lower()
        if suffix in (".xlsx", ".h5", ".hdf5") or (suffix in (".csv", ".txt") and p not in meta and sniff(p)) \
                or (suffix == ".zip" and (looks_like_sensorlogger(p) or looks_like_phyphox(p))):
            singles.append([p])
        elif suffix == ".csv" and p not in meta:
            ignored.append(p.name)
    return groups + singles, ignored


def _settle_session_clock(raws: list[RawRecording]) -> list[RawRecording]:
    """MetaBase streams whose epoch a spreadsheet mangled, put on the UTC epoch of the session's other
    MetaBase files (:func:`.metabase.settle_local_time`; the phone is the same clock)."""
    streams = [s for r in raws for s in r.streams]
    if not any(s.time_base == "epoch-local" for s in streams):
        return raws
    settled = iter(settle_local_time(streams, final=True))
    out = []
    for r in raws:
        acc, gyr, mag = next(settled), next(settled), next(settled)
        extra = tuple(n for st in (acc, gyr, mag) for n in st.notes if n not in r.notes)
        out.append(replace(r, acc=acc, gyr=gyr, mag=mag, notes=r.notes + extra))
    return out


def _metadata(manifest: dict[str, Any], mpath: Path | None, recs: dict[tuple[str, str], RawRecording],
              notes: list[str]) -> SessionMetadata:
    found: dict[str, Recognition | None] = {}
    task_first = sorted(recs.values(), key=lambda r: r.role is None or r.role.value != "task")
    for key in ("patient_id", "side", "step_height_m", "date", "trial"):
        if key in manifest:
            value = manifest[key]
            if key == "side":
                side = recognise_side(str(value), "session.json")
                if side is None:
                    raise IngestionError("manifest.bad_side", file=mpath, value=str(value)[:60])
                value = side.value
            if key == "step_height_m" and not (isinstance(value, (int, float)) and 0.0 < value < 1.0):
                raise IngestionError("manifest.bad_step_height", file=mpath, value=repr(value)[:60])
            found[key] = Recognition(value, "session.json", key)
            continue
        values = [r.extras[key] for r in task_first if key in r.extras]
        if len({str(v.value) for v in values}) > 1:
            notes.append(Note.of("names_disagree", key=key, values=str(sorted({str(v.value) for v in values})),
                                 used=repr(values[0].value)))
        found[key] = values[0] if values else None
    if found["step_height_m"] is None and ("thigh", "task") in recs:
        task = recs[("thigh", "task")]
        if parse_thesis_name(task.label) is not None:
            found["step_height_m"] = Recognition(LOW_STEP_M, task.role.method if task.role else "file name",
                                                 "no -H suffix (thesis: the 17 cm step)")
    return SessionMetadata(**found)


def _ambiguity(rec: RawRecording) -> list:
    """The ``why`` of ``hint.unrecognised``: the ambiguous labels of ``rec``'s notes (``word.ambiguity``), or ""."""
    found = [n.params["ambiguous"] for n in rec.notes if isinstance(n, Note) and "ambiguous" in n.params]
    return {"code": "word.ambiguity", "params": {"reasons": found}} if found else ""


def load_session(path: str | os.PathLike, *, expected_fs_hz: float | None = 100.0,
                 roles: Sequence[str] = ROLES, required: Sequence[str] | None = None) -> Session:
    """Read and align one session folder (or its ``session.json``) of one knee; see the package docstring.

    expected_fs_hz : accelerometer/gyroscope rate the protocol uses (refuse others beyond 3 %); ``None``
        accepts the files' own rate.   roles : the recordings read (others found are ignored).
    required : the recordings every sensor must have (default ``("task",)`` when ``roles`` holds the task, else all
        of ``roles``).  The others of ``roles`` are optional — the pipeline then calibrates without them (issue 14
        §3: no figure-eight, no supine, the task alone), and a note says so — but one that a sensor has, the other
        sensor must have too (a forgotten file is named, not silently worked around).
    A folder with both knees (four sensors, :func:`load_knees`) is refused here (``session.two_knees``).
    """
    folder, mpath, manifest, entries, raws, notes, ignored = _read_folder(path)
    if _knee_groups(mpath, manifest, entries, raws) is not None:
        raise IngestionError("session.two_knees", file=folder)
    return _assemble(folder, mpath, manifest, list(zip(range(len(entries)), entries, raws)), notes, ignored,
                     expected_fs_hz, roles, required)


def load_knees(path: str | os.PathLike, *, expected_fs_hz: float | None = 100.0,
               roles: Sequence[str] = ROLES, required: Sequence[str] | None = None) -> dict[str, Session]:
    """Every knee of a session folder: ``{side: Session}`` (one entry for a one-knee folder, keyed by its side or
    ``""`` when nothing names it; two, ``"left"`` and ``"right"``, for both knees).

    Both knees in one folder: four sensors (both thighs, both shanks) whose recordings each name their side, in
    the file name (right/derecha/direita, left/izquierda/esquerda, :mod:`.labels`) or in ``session.json``
    (``recordings[i].side``).  Each side must have both segments; each knee is then read as its own session
    (:func:`load_session`'s rules per side; its ``metadata.side`` is that side, so adduction and rotation take the
    side's sign).  The manifest's ``side`` then names the involved knee (the patient's side), not the recordings':
    each knee's ``patient_side`` (``manifest.bad_side`` when it is not a side).
    Two one-knee sessions paired: ``session.json`` ``"paired_session": "../other-folder"`` (a folder beside this
    one, of the other knee; its own ``paired_session`` is not followed); the patient's side is then this folder's
    when its ``session.json`` names a ``side``.
    """
    folder, mpath, manifest, entries, raws, notes, ignored = _read_folder(path)
    groups = _knee_groups(mpath, manifest, entries, raws)
    if groups is None:
        one = _assemble(folder, mpath, manifest, list(zip(range(len(entries)), entries, raws)), notes, ignored,
                        expected_fs_hz, roles, required)
        knees = {one.metadata.value("side") or "": one}
        paired = manifest.get("paired_session")
        if paired is None:
            return knees
        other_folder = (folder / paired).resolve()
        if not other_folder.is_dir() or other_folder == folder.resolve():
            raise IngestionError("manifest.paired_not_found", file=mpath, value=str(paired)[:120])
        other = load_session(other_folder, expected_fs_hz=expected_fs_hz, roles=roles, required=required)
        sides = (one.metadata.value("side"), other.metadata.value("side"))
        if None in sides or sides[0] == sides[1]:
            raise IngestionError("manifest.paired_same_side", file=mpath, other=other_folder.name,
                                 side=str(sides[0]), other_side=str(sides[1]))
        patient = sides[0] if manifest.get("side") is not None else None  # this folder's side, when it names one
        return {side: replace(s, patient_side=patient) for side, s in zip(sides, (one, other))}
    patient = manifest.get("side")
    if patient is not None:
        found = recognise_side(str(patient), "session.json")
        if found is None:
            raise IngestionError("manifest.bad_side", file=mpath, value=str(patient)[:60])
        patient = found.value
    out = {}
    for side in sorted(groups):
        picked = groups[side]
        side_manifest = {**manifest, "side": side, "split": knee_split(manifest.get("split"), side, mpath)}
        out[side] = replace(_assemble(folder, mpath, side_manifest, picked, list(notes), ignored, expected_fs_hz,
                                      roles, required), patient_side=patient)
    return out


def _read_folder(path: str | os.PathLike):
    """The folder, its manifest (path and content), the entries to read, each entry's recording as read (on one
    session clock), and the notes and hints of the ``.csv`` files left out."""
    path = Path(path)
    folder = path.parent if path.is_file() else path
    if not folder.is_dir():
        raise IngestionError("session.no_folder", file=path)
    mpath = folder / MANIFEST if (folder / MANIFEST).is_file() else None
    manifest = _read_manifest(mpath) if mpath else {}
    entries = manifest.get("recordings")
    left_out: list[str] = []
    if entries is None:  # discovered files are already paths inside folder: keep only their names
        groups, left_out = _discover(folder)
        entries = []
        for g in groups:
            if len(g) == 1 and g[0].suffix.lower() in (".h5", ".hdf5"):   # one recording per sensor of the file
                entries += [{"files": [g[0].name], "sensor": sid} for sid in list_sensors(g[0])]
            else:
                entries.append({"files": [p.name for p in g]})
    notes: list[str] = [Note.of("csv_ignored", file=name) for name in left_out]
    ignored = [{"code": "hint.ignored_csv", "params": {"file": name}} for name in left_out]
    if not entries:
        names = sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
        raise IngestionError("session.no_recordings", file=folder, count=len(names),
                             found=", ".join(names[:8]) + (", ..." if len(names) > 8 else "") if names else "-",
                             hint=ignored)
    raws = [read_recording([folder / f for f in e["files"]], sheet=e.get("sheet"), hint=ignored, settle=False,
                           sensor=e.get("sensor")) for e in entries]
    return folder, mpath, manifest, entries, _settle_session_clock(raws), notes, ignored


def _segment_of(mpath: Path | None, manifest: dict[str, Any], i: int, entry: dict, rec: RawRecording
                ) -> Recognition | None:
    """The segment of recording ``rec`` (entry ``i`` of the manifest): ``recordings[i].segment`` of
    ``session.json``, else the segment ``sensors`` gives its sensor's serial, else the one its name gives."""
    segment = rec.segment
    sensors = {str(k).replace(":", "").upper(): v for k, v in manifest.get("sensors", {}).items()}
    if rec.sensor_id and rec.sensor_id in sensors:
        segment = _manifest_word(mpath, f"sensors[{rec.sensor_id!r}]", sensors[rec.sensor_id], "segment")
    if "segment" in entry:
        segment = _manifest_word(mpath, f"recordings[{i}].segment", entry["segment"], "segment")
    return segment


def _knee_groups(mpath: Path | None, manifest: dict[str, Any], entries: list[dict], raws: list[RawRecording]
                 ) -> dict[str, list[tuple[int, dict, RawRecording]]] | None:
    """The recordings of each knee, ``{side: [(index, entry, recording)]}``, when the folder holds both knees (both
    sides named, each with a thigh and a shank recording); None for a one-knee folder (files that disagree on the
    side there stay the provenance check's to refuse).  With both sides named, a recording naming none is refused
    (``session.side_unknown``): it cannot be given to either knee."""
    sides: list[str | None] = []
    segs: dict[str, set[str]] = {}
    for i, (e, rec) in enumerate(zip(entries, raws)):
        side = rec.extras.get("side")
        if "side" in e:
            side = recognise_side(str(e["side"]), "session.json")
            if side is None:
                raise IngestionError("manifest.bad_side", file=mpath, value=str(e["side"])[:60])
        segment = _segment_of(mpath, manifest, i, e, rec)
        sides.append(None if side is None else side.value)
        if side is not None and segment is not None:
            segs.setdefault(side.value, set()).add(segment.value)
    unnamed = [rec.files[0].name for rec, side in zip(raws, sides) if side is None]
    if len(segs) < 2 or (not unnamed and not all(set(SEGMENTS) <= v for v in segs.values())):
        return None  # one knee (its files naming two sides are the provenance check's to refuse)
    if unnamed:  # both sides named, and recordings that name none: they belong to no knee
        raise IngestionError("session.side_unknown", file=unnamed[0], files=", ".join(unnamed))
    out: dict[str, list[tuple[int, dict, RawRecording]]] = {}
    for i, (e, rec, side) in enumerate(zip(entries, raws, sides)):
        out.setdefault(side, []).append((i, e, rec))
    return out


def _assemble(folder: Path, mpath: Path | None, manifest: dict[str, Any], picked: list[tuple[int, dict, RawRecording]],
              notes: list[str], ignored: list[dict], expected_fs_hz: float | None, roles: Sequence[str],
              required: Sequence[str] | None) -> Session:
    """One knee's :class:`Session` from its recordings as read (``picked``: index in the manifest, entry, recording)."""
    recs: dict[tuple[str, str], RawRecording] = {}
    continuous: dict[str, list[tuple[RawRecording, str]]] = {}
    unrecognised: list[dict] = []
    for i, e, rec in picked:
        segment, role = _segment_of(mpath, manifest, i, e, rec), rec.role
        if "role" in e:
            role = _manifest_word(mpath, f"recordings[{i}].role", e["role"], "role")
        if segment is not None and (role is None or role.value == CONTINUOUS):  # split below (.split)
            continuous.setdefault(segment.value, []).append(
                (replace(rec, segment=segment, role=role), "role" if role else "only recording"))
            continue
        if segment is None or role is None or role.value not in roles:
            if role is None or segment is None:
                what = {"code": "word.role_segment" if role is None and segment is None else
                        "word.role" if role is None else "word.segment"}
                unrecognised.append({"code": "hint.unrecognised",
                                     "params": {"file": rec.files[0].name, "what": what, "why": _ambiguity(rec)}})
            continue
        rec = RawRecording(rec.acc, rec.gyr, rec.mag, rec.fmt, segment, role, rec.label, rec.sensor_id,
                           rec.extras, rec.notes)
        key = (segment.value, role.value)
        if key in recs:
            raise IngestionError("session.recording_twice", file=rec.files[0], other=recs[key].files[0],
                                 role=role.value, segment=segment.value)
        recs[key] = rec
    recs, splits, split_notes = split_session(continuous, recs, expected_fs_hz, manifest.get("split"), mpath)
    notes += split_notes
    for r in left_unsplit(continuous, splits):
        unrecognised.append({"code": "hint.unrecognised", "params": {"file": r.files[0].name,
                                                                     "what": {"code": "word.role"},
                                                                     "why": _ambiguity(r)}})
    hint = ignored + unrecognised + [{"code": "hint.naming", "params": {"manifest": MANIFEST}}]
    segs = {s for s, _ in recs}
    if len(segs) < 2:
        raise IngestionError("session.one_sensor" if segs else "session.no_sensor", file=folder,
                             segment=next(iter(segs), ""), hint=hint)
    if required is None:
        required = ("task",) if "task" in roles else tuple(roles)
    present = {r for _, r in recs}
    missing = [{"code": "word.role_of", "params": {"role": {"code": f"word.{r}"}, "segment": {"code": f"word.{s}"}}}
               for s in SEGMENTS for r in roles if (s, r) not in recs and (r in required or r in present)]
    if missing:
        raise IngestionError("session.missing_recordings", file=folder, missing=missing, hint=hint)
    notes += [Note.of(f"no_{r}", file=folder) for r in roles if r not in present and r not in required]
    notes += [Note.of("file_unrecognised", **u["params"]) for u in unrecognised]
    field = manifest.get("mag_field_ut")
    if field is not None:
        if not 10.0 <= field <= 100.0:
            raise IngestionError("manifest.bad_field", file=mpath, value=repr(field))
        recs = {k: replace(r, mag=replace(r.mag, field_ut=float(field))) if r.mag.mag_unit == "normalised"
                and r.mag.field_ut is None else r for k, r in recs.items()}
    for rec in recs.values():
        check_gyro_unit(rec.acc, rec.gyr)
    fs = {key: check_rates(rec, expected_fs_hz) for key, rec in recs.items()}
    aligned = {key: align_recording(rec, fs[key], *key) for key, rec in recs.items()}
    task = None
    processed = dict(aligned)  # what the pipeline uses: the task pair on its common grid, whose notes it gives
    if "task" in roles:
        task = align_pair(recs[("thigh", "task")], recs[("shank", "task")], fs[("thigh", "task")])
        processed[("thigh", "task")], processed[("shank", "task")] = task
    for key, rec in recs.items():
        notes += [n.prefixed(*key) if isinstance(n, Note) else f"{key[0]} {key[1]}: {n}"
                  for n in list(rec.notes) + processed[key].flags["notes"]]
    metadata = _metadata(manifest, mpath, recs, notes)
    return Session(folder=folder, recordings=aligned, raw=recs, task=task, metadata=metadata, manifest=mpath,
                   notes=tuple(dict.fromkeys(notes)), manifest_data=manifest, splits=tuple(splits))


__all__ = ["MANIFEST", "load_knees", "load_session", "read_recording"]
