"""A stored session as a folder the ingestion can read: files, ``session.json`` manifest, ingestion check.

The database holds the facts typed in the browser or sent by a hospital system (patient side, step height,
the segment/role chosen for an upload); the ingestion (:func:`app.pipeline.ingestion.load_knees`) reads a folder.
:func:`materialise` bridges the two: it copies every recording of a session out of the blob store
(checksums verified) under its original file name into a temporary folder and writes the ``session.json``
that :mod:`app.pipeline.ingestion.session` documents:

* ``side`` (the patient's), ``patient_id`` (external id), ``date``, ``step_height_m`` when known, and the
  report-only keys ``name``, ``professional``, ``weight_kg``, ``height_m``, ``observations``;
* ``recordings`` only when an upload declared a segment or role: every file is then listed (MetaBase streams
  grouped into their recording), with the declared segment/role — the rest is still recognised from names;
* ``split``: the cuts the clinician confirmed or moved in the wizard (``KneeSession.split``);
* a ``session.json`` uploaded with the recordings is the base; the database's facts win over its keys, and its
  identity and person keys (:data:`IDENTITY_KEYS`: name, record number, birth date, sex, clinic, identifier
  system, professional, weight, height, observations) are dropped: in the web path the database is the only
  source of who the report is about, so a file's identity is never printed, even where the database has none.

:func:`check_ingestion` runs the ingestion on that folder and returns the contract's Ingestion object.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from app.store.models import KneeSession, Patient, Recording
from app.pipeline.ingestion import MANIFEST, IngestionError, load_knees
from app.pipeline.ingestion.labels import recognise_role, recognise_segment
from app.pipeline.ingestion.metabase import group_metabase_files, parse_file_name
from app.pipeline.ingestion.session import parse_manifest
from app.pipeline.service_messages import item, recognised_item, render
from app.store.blobs import BlobStore


#: the Ingestion object of a session without recordings (the API answers it too before any check ran)
NO_RECORDINGS: dict[str, Any] = {"ok": False, "messages": [], "error": render("session.no_files_yet", {}),
                                  "error_item": item("session.no_files_yet", {}, render("session.no_files_yet", {}))}


#: the keys of an uploaded session.json the server never passes on (module docstring): the reports' identity and
#: person facts come from the database alone
IDENTITY_KEYS = ("patient_id", "name", "birth_date", "sex", "clinic", "identifier_system", "professional",
                 "weight_kg", "height_m", "observations")


def _number(x: Any) -> float | None:
    return None if x is None else float(x)


def build_manifest(session: KneeSession, patient: Patient, recordings: Sequence[Recording],
                   uploaded: dict[str, Any] | None = None, *, clinic: str = "",
                   identifier_system: str | None = None) -> dict[str, Any]:
    """The ``session.json`` of ``session`` (module docstring).  ``clinic`` (its name) and ``identifier_system``
    (the URI of the record numbers' namespace, ``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM``) go with the patient's birth
    date and sex into the reports' identity line (issue 17 §3).

    An uploaded manifest may only name this session's stored files, by their bare names: anything else (a
    path, ``..``, a file that was not uploaded) raises :class:`IngestionError`, so a manifest can never make
    the ingestion read a file outside the session's own folder."""
    if uploaded is not None and not isinstance(uploaded, dict):
        raise IngestionError("manifest.stored_not_object", file=MANIFEST, kind=type(uploaded).__name__)
    manifest: dict[str, Any] = {k: v for k, v in (uploaded or {}).items() if k not in IDENTITY_KEYS}
    stored = {r.file_name for r in recordings if r.file_name != MANIFEST}
    listed = manifest.get("recordings") or []
    if not isinstance(listed, list):
        raise IngestionError("manifest.stored_recordings_not_list", file=MANIFEST)
    for entry in listed:
        files = entry.get("files") if isinstance(entry, dict) else None
        for name in files if isinstance(files, list) else [files]:
            if not isinstance(name, str) or Path(name).name != name or name not in stored:
                raise IngestionError("manifest.not_uploaded", file=MANIFEST, name=repr(name)[:80])
    facts = {
        "side": session.knee or patient.side, "patient_id": patient.external_id, "date": session.date.isoformat(),
        "step_height_m": _number(session.step_height_m), "name": patient.name,
        "professional": session.professional, "weight_kg": _number(patient.mass_kg),
        "height_m": None if patient.height_cm is None else patient.height_cm / 100.0,
        "observations": session.notes, "birth_date": None if patient.birth_date is None else patient.birth_date.isoformat(),
        "sex": patient.sex, "clinic": clinic, "identifier_system": identifier_system,
    }
    manifest |= {k: v for k, v in facts.items() if v not in (None, "")}
    if session.split:  # the clinician's cuts, confirmed in the wizard (app.store.recordings.set_split)
        manifest["split"] = session.split
    data = [r for r in recordings if r.file_name != MANIFEST]
    if any(r.segment or r.role for r in data):
        by_name = {r.file_name: r for r in data}
        meta = [Path(n) for n in by_name if n.lower().endswith(".csv") and parse_file_name(Path(n))]
        groups = [sorted(p.name for p in g.values()) for g in group_metabase_files(meta).values()] if meta else []
        grouped = {n for g in groups for n in g}
        groups += [[n] for n in by_name if n not in grouped]
        entries = []
        for names in groups:
            entry: dict[str, Any] = {"files": names}
            for key in ("segment", "role"):
                values = {getattr(by_name[n], key) for n in names}
                if len(values) == 1 and None not in values:
                    entry[key] = values.pop()
            entries.append(entry)
        manifest["recordings"] = entries
    return manifest


def uploaded_manifest(store: BlobStore, recordings: Sequence[Recording]) -> dict[str, Any] | None:
    """The ``session.json`` uploaded among ``recordings`` (parsed, within the manifest caps), or None."""
    for rec in recordings:
        if rec.file_name == MANIFEST:
            try:  # within the manifest caps: too deep or too large is an IngestionError (issue 16, finding 5)
                uploaded = parse_manifest(store.read(rec.sha256).decode("utf-8"), MANIFEST)
            except (UnicodeDecodeError, json.JSONDecodeError):
                raise IngestionError("manifest.stored_not_json", file=MANIFEST) from None
            if not isinstance(uploaded, dict):
                raise IngestionError("manifest.stored_not_object", file=MANIFEST, kind=type(uploaded).__name__)
            return uploaded
    return None


#: the folder of a paired session's partner, beside the session's own (``session.json`` ``"paired_session"``)
PAIRED_FOLDER = "paired-session"


def _write_session(store: BlobStore, folder: Path, session: KneeSession, patient: Patient,
                   recordings: Sequence[Recording], extra: dict[str, Any] | None = None, *, clinic: str = "",
                   identifier_system: str | None = None) -> None:
    """The session's files and manifest (``extra`` keys added to it; ``clinic`` and ``identifier_system`` as
    :func:`build_manifest`'s) into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    uploaded = uploaded_manifest(store, recordings)
    for rec in recordings:
        if rec.file_name != MANIFEST:
            store.copy_to(rec.sha256, folder / rec.file_name)
    manifest = build_manifest(session, patient, recordings, uploaded, clinic=clinic,
                              identifier_system=identifier_system)
    manifest.pop("paired_session", None)  # only the database pairs stored sessions
    manifest |= extra or {}
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=2, ensure_ascii=False), encoding="utf-8")


@contextmanager
def materialise(store: BlobStore, tmp_root: Path, session: KneeSession, patient: Patient,
                recordings: Sequence[Recording],
                paired: tuple[KneeSession, Sequence[Recording]] | None = None, *, clinic: str = "",
                identifier_system: str | None = None) -> Iterator[Path]:
    """A temporary folder with the session's files and manifest (removed on exit; ``clinic`` and
    ``identifier_system`` as :func:`build_manifest`'s).  ``paired``: the session it is paired with and its
    recordings (:func:`app.store.pairing.partner_files`): those go into a sibling folder (:data:`PAIRED_FOLDER`)
    that the manifest names as ``paired_session``, so the ingestion reads both knees."""
    tmp_root.mkdir(parents=True, exist_ok=True)
    root = Path(tempfile.mkdtemp(prefix=f"session-{session.id}-", dir=tmp_root))
    folder = root / "session"
    try:
        extra = None
        if paired is not None:
            _write_session(store, root / PAIRED_FOLDER, paired[0], patient, paired[1], clinic=clinic,
                           identifier_system=identifier_system)
            extra = {"paired_session": f"../{PAIRED_FOLDER}"}
        _write_session(store, folder, session, patient, recordings, extra, clinic=clinic,
                       identifier_system=identifier_system)
        yield folder
    finally:
        shutil.rmtree(root, ignore_errors=True)


def public_message(text: str, folder: Path | None) -> str:
    """``text`` without the server's temporary path ``folder`` (nor its paired session's)."""
    if folder is None:
        return text
    paired = str(folder.parent / PAIRED_FOLDER)
    text = text.replace(paired + "/", "").replace(paired, "the paired session")
    return text.replace(str(folder) + "/", "").replace(str(folder), "the session")


def _public(value: Any, folder: Path | None) -> Any:
    """``value`` (a message's parameter) with the server's temporary path ``folder`` taken out of its strings."""
    if isinstance(value, str):
        return public_message(value, folder)
    if isinstance(value, dict):
        return {k: _public(v, folder) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_public(v, folder) for v in value]
    return value


def _note_item(note: str, folder: Path | None) -> dict[str, Any]:
    params = _public(dict(getattr(note, "params", {}) or {}), folder)
    return item(None, params, public_message(str(note), folder), note=bool(params.get("variant")))


def file_facts(loaded) -> dict[str, dict[str, str]]:
    """What the reading found of each stored file of a loaded session: ``devices`` (the sensor serial its content
    or name carries, every format that has one: :attr:`app.pipeline.ingestion.RawRecording.sensor_id`) and
    ``segments`` and ``roles`` (the segment and recording it was recognised as), by file name; stored with the
    recordings (:func:`app.store.checks.save_ingestion`) for the server's same-sensor check and the wizard's zones
    (a file dropped without a zone is shown in the zone it was recognised for)."""
    devices, segments, roles = {}, {}, {}
    for (seg, role), rec in loaded.recordings.items():
        for f in rec.source.get("files", ()):
            name = Path(f).name
            segments[name], roles[name] = seg, role
            if rec.source.get("sensor_id"):
                devices[name] = str(rec.source["sensor_id"])[:64]
    return {"devices": devices, "segments": segments, "roles": roles}


def check_ingestion(store: BlobStore, tmp_root: Path, session: KneeSession, patient: Patient,
                    recordings: Sequence[Recording],
                    paired: tuple[KneeSession, Sequence[Recording]] | None = None) -> dict[str, Any]:
    """The contract's Ingestion ``{"ok", "messages", "error"}`` of the session's stored files (English), with
    ``items`` and ``error_item``: the same messages as codes and params (:func:`app.pipeline.service_messages.item`),
    which the API renders in the reader's language; and ``splits``, where each continuous recording was cut
    (:meth:`app.pipeline.ingestion.split.Split.to_dict`, with its trace), for the wizard to show and move.
    ``paired``: the partner of a paired session (:func:`materialise`): both knees are checked."""
    if not [r for r in recordings if r.file_name != MANIFEST]:
        return dict(NO_RECORDINGS)
    folder = None
    try:
        with materialise(store, tmp_root, session, patient, recordings, paired) as folder:
            knees = load_knees(folder)  # one knee, or both (four sensors)
            items, splits, devices, segments, roles = [], {}, {}, {}, {}
            for side, loaded in sorted(knees.items()):
                if len(knees) > 1:
                    items.append(item(f"session.knee.{side}", {}, render(f"session.knee.{side}", {}, "en")))
                items += [recognised_item(seg, role, rec.source) for (seg, role), rec in sorted(loaded.recordings.items())]
                items += [n for n in (_note_item(n, folder) for n in loaded.notes) if n not in items]
                knee = f"{side}_" if len(knees) > 1 else ""
                splits.update({f"{knee}{s.segment}": s.to_dict(trace=True) for s in loaded.splits})
                facts = file_facts(loaded)
                devices.update(facts["devices"])
                segments.update({name: f"{knee}{seg}" for name, seg in facts["segments"].items()})
                roles.update(facts["roles"])
            return {"ok": True, "messages": [i["text"] for i in items], "error": None, "items": items,
                    "error_item": None, "splits": splits, "devices": devices, "segments": segments, "roles": roles}
    except IngestionError as exc:
        text = public_message(str(exc), folder)
        return {"ok": False, "messages": [], "error": text, "items": [],
                "error_item": item(exc.code, _public(dict(exc.params), folder), text), **named_facts(recordings)}
    except (ValueError, OSError) as exc:
        text = public_message(str(exc), folder)
        return {"ok": False, "messages": [], "error": text, "items": [], "error_item": None,
                **named_facts(recordings)}


def named_facts(recordings: Sequence[Recording]) -> dict[str, dict[str, str]]:
    """``segments`` and ``roles`` of the files whose names say both (:func:`app.pipeline.ingestion.labels.
    recognise_segment` / ``recognise_role``), for a check that failed before it recognised anything: the wizard
    then still shows each such file in its zone (a rejected one red there) instead of under "other files".  A name
    with two candidate words, or without one of the two, is left out."""
    segments, roles = {}, {}
    for r in recordings:
        if r.file_name == MANIFEST:
            continue
        try:
            seg, role = recognise_segment(r.file_name), recognise_role(r.file_name)
        except ValueError:  # two words match: the check alone can tell
            continue
        if seg is not None and role is not None:
            segments[r.file_name], roles[r.file_name] = seg.value, role.value
    return {"segments": segments, "roles": roles}


__all__ = ["IDENTITY_KEYS", "NO_RECORDINGS", "PAIRED_FOLDER", "build_manifest", "uploaded_manifest", "check_ingestion", "file_facts",
           "materialise", "named_facts",
           "public_message"]
