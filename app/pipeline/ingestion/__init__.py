"""Ingestion: session files → aligned recordings in project units (acc m/s², gyr rad/s, mag µT, t s).

All unit conversion of the project happens here, once (:mod:`.units`).

Public API
----------
``load_session(path, *, expected_fs_hz=100.0, roles=ROLES) -> Session``
    Discover the files of one session folder (or use its ``session.json``), recognise each
    recording's segment (thigh/shank) and role (``mag_calibration``, ``standing``, ``lying``, ``task``),
    read and check them, and align them (:mod:`.align`).
``load_knees(path, *, expected_fs_hz=100.0, roles=ROLES) -> {side: Session}``
    Every knee of a folder: one for a two-sensor session, ``"left"`` and ``"right"`` for four sensors whose
    recordings name their side (file name or ``session.json`` ``recordings[i].side``) or for a session paired
    with another folder (``session.json`` ``paired_session``); ``load_session`` refuses a two-knee folder.
``Session.recording(segment, role) -> AlignedRecording``
    acc, gyr, mag ``(N, 3)`` on one grid ``t_s`` (from 0) at ``fs_hz``; ``source`` (files, format, how
    segment and role were recognised), ``flags`` (measured rates, trimmed seconds, NaN rows, notes).
``Session.task_pair() -> (thigh, shank)``
    The two task recordings on one common grid (same ``t_s``), aligned on their time stamps.
``Session.metadata``: :class:`SessionMetadata` (patient_id, side, step_height_m, date, trial — each a
    :class:`Recognition` saying whether the file name, the MetaBase label or ``session.json`` gave it).
``Session.notes``: sentences worth showing the user (sheet chosen, stream cut, default step height...); those
    the reports translate are :class:`Note` (a ``str`` with ``params``: variant, segment, role, values).
``read_recording(files, sheet=None) -> RawRecording``: one recording as read (streams with own stamps).
``read_metabase_csv``, ``read_thesis_xlsx``, ``read_generic_csv``: single-file readers → :class:`Stream`.
``align_recording``, ``align_pair``: the alignment on its own.
Writers (demo, tests): ``write_metabase_csv``, ``write_recording_metabase``, ``write_session_metabase``,
``write_thesis_xlsx``, ``write_generic_csv``; ``simulated_streams(imu, epoch0_s, run_on_s=...)`` turns a simulated
sensor into writer input with the phone's stamps.
Every problem a user can cause raises :class:`IngestionError` (a ``ValueError``) whose one message names
the file and says what to do.  Readers never write.

Formats (recognised by name and content; every reader converts to SI once, in :mod:`.units`)
-------
* MetaBase CSV, one file per stream (:mod:`.metabase`): ``[{label}_]{device}_{datetime}_{MAC}_{Stream}_{rate}Hz
  [_{firmware}].csv`` with any user-chosen device name (``MetaWear``, ``Werable1``...); header ``epoch (ms),time
  (…),elapsed (s),x-axis (g),…`` or ``epoc (ms),timestamp (…),…``; g, deg/s, T.  Time base: epoch ms (the
  phone's clock, shared by both sensors); rounded by a spreadsheet (``1.63552E+12``): rebuilt from the name's
  start + ``elapsed (s)``, noted.
* Thesis Excel (:mod:`.excel`, seed 004 Fig. 8.6): A–D elapsed + acc (g), E–G gyro (deg/s), H–K elapsed + mag
  (T), L–M elapsed + temperature; names ``{calibracion-sensor|standing|laydown|step}-{muslo|pierna}-{ID}-
  {ddmmyyyy}-{n}[-H].xlsx`` (H = the 34 cm step, else 17 cm).  Time base: elapsed s (sensors assumed to start
  together).
* Generic CSV (:mod:`.generic`): ``time (s),acc_x (g),…,gyr_x (deg/s),…,mag_x (uT),…`` with units in the header;
  ``mag_x (normalised [48.5 uT])`` for a normalised magnetometer.
* Xsens MT Manager text/CSV export (:mod:`.xsens`): ``//`` preamble, ``PacketCounter SampleTimeFine Acc_X … Gyr_X …
  Mag_X …``; m/s², rad/s, **normalised** magnetometer.
* Shimmer Consensys CSV (:mod:`.shimmer`): ``sep=`` line, ``Shimmer_XXXX_<signal>_<axis>_CAL`` names, CAL and units
  rows; m/(s^2), deg/s, local_flux (gauss-scaled), Unix ms.
* APDM Opal HDF5 (:mod:`.opal`, ``.h5``, format 5): ``/Sensors/<id>/{Accelerometer,Gyroscope,Magnetometer,Time}``;
  one recording per sensor of a file, its segment and side from the sensor's label.
* Sensor Logger phone app zip export (:mod:`.sensorlogger`, ``.zip``): ``TotalAcceleration`` or ``Accelerometer``
  + ``Gravity`` (specific force), ``Gyroscope`` rad/s, ``Magnetometer`` µT, ``time`` ns since 1970.
* phyphox exports (:mod:`.phyphox`): the ``.zip`` of set CSVs (+ ``meta/time.csv``: the phone's clock), the single
  ``.csv``, ``.xlsx``; ``Time (s)``, ``Acceleration x (m/s^2)``, ``Gyroscope x (rad/s)``, ``Magnetic field x (µT)``.
* One continuous recording per sensor of the whole protocol (:mod:`.split`): split into the four roles,
  ``Session.splits``.
* Any CSV (MetaBase, generic, Shimmer; Xsens with ``;``): ``;`` between fields with decimal commas (Excel in
  es/pt) is read; a cut last line and rows repeated exactly are dropped; each repair is a :class:`Note`.
* ``session.json`` (:mod:`.session`): files → segment and role (``sensor`` for an APDM file) and side (both knees),
  MAC → segment, patient_id, side, step height, ``mag_field_ut`` (the local field for a normalised magnetometer),
  ``paired_session`` (the other knee's folder).

A **normalised magnetometer** (Xsens, the generic ``normalised`` unit) has no µT scale.  It stays as the file
gives it (norm ≈ 1): ``Stream.mag_unit == "normalised"`` and ``Stream.field_ut`` (declared strength or ``None``);
after alignment ``AlignedRecording.mag_normalised`` and ``flags["mag_unit"]``, ``flags["mag_field_ut"]``; a note
``mag_normalised``.  The pipeline must not fit a µT ellipsoid to it (the vendor calibrated it).

Messages and facts
------------------
Every :class:`IngestionError` carries ``code`` and ``params`` (``str(exc)`` is English; ``exc.message(lang)`` gives
es/en/pt from :mod:`.messages`); every repair or remark is a :class:`Note` with ``params["variant"]`` and
``note.message(lang)``.  :mod:`.provenance` exposes per-recording facts (side, start date-time, patient id,
sensor id) and pure checks (side, dates, patient id, sensors) whose findings are codes + params too.

Decisions on bad input
----------------------
Missing recording, only one sensor, unknown or implausible units (mg, mT, rad/s declared deg/s: detected
from magnitudes and from the gyroscope/accelerometer rotation consistency, :mod:`.units`), empty,
header-only or truncated files, non-numeric cells, duplicated or out-of-order stamps, acc/gyr rates more
than 3 % from ``expected_fs_hz`` (50 Hz data: refused with advice; ``expected_fs_hz=None`` accepts it),
an Excel workbook with none or several sheets in the layout (one such sheet among others is used and noted):
each raises :class:`IngestionError`.  Swapped segments cannot be told from the files; the pipeline checks
them on the signals.  NaN rows in a stream are missing samples (NaN on the grid inside gaps), not errors.
"""

from app.pipeline.ingestion.align import align_pair, align_recording
from app.pipeline.ingestion.excel import read_thesis_xlsx, write_thesis_xlsx
from app.pipeline.ingestion.generic import read_generic_csv, write_generic_csv
from app.pipeline.ingestion.metabase import read_metabase_csv, write_metabase_csv, write_recording_metabase
from app.pipeline.ingestion.model import (KINDS, ROLES, SEGMENTS, AlignedRecording, IngestionError, Note, RawRecording,
                                 Recognition, Session, SessionMetadata, Stream)
from app.pipeline.ingestion.messages import LANGUAGES, message_dict, render
from app.pipeline.ingestion.opal import read_opal, write_opal
from app.pipeline.ingestion.phyphox import read_phyphox, write_phyphox
from app.pipeline.ingestion.provenance import (Finding, RecordingFacts, check_all, check_dates, check_patient,
                                               check_sensors, check_side, recording_facts, session_facts)
from app.pipeline.ingestion.session import MANIFEST, load_knees, load_session, read_recording
from app.pipeline.ingestion.sensorlogger import read_sensorlogger, write_sensorlogger
from app.pipeline.ingestion.shimmer import read_shimmer, write_shimmer
from app.pipeline.ingestion.writers import session_label, simulated_streams, write_session_metabase
from app.pipeline.ingestion.xsens import read_xsens, write_xsens

__all__ = [
    "LANGUAGES", "Finding", "RecordingFacts", "check_all", "check_dates", "check_patient", "check_sensors",
    "check_side", "message_dict", "read_opal", "read_phyphox", "write_phyphox", "read_shimmer", "read_xsens", "recording_facts", "render",
    "session_facts", "write_opal", "write_shimmer", "write_xsens", "read_sensorlogger", "write_sensorlogger",
    "KINDS", "MANIFEST", "ROLES", "SEGMENTS", "AlignedRecording", "IngestionError", "Note", "RawRecording",
    "Recognition",
    "Session", "SessionMetadata", "Stream", "align_pair", "align_recording", "load_knees", "load_session", "read_generic_csv",
    "read_metabase_csv", "read_recording", "read_thesis_xlsx", "session_label", "simulated_streams",
    "write_generic_csv",
    "write_metabase_csv", "write_recording_metabase", "write_session_metabase", "write_thesis_xlsx",
]
