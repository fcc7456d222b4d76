"""FHIR R4 export of one knee session: a ``DiagnosticReport`` for hospital systems (issue 5, item 6).

:func:`diagnostic_report` turns a session's ``results.json`` and its PDF report into one JSON-ready
FHIR R4 (4.0.1) ``DiagnosticReport``; the API route ``GET /api/v1/fhir/DiagnosticReport/{session_id}``
returns it as is.  Pure: no database, no web framework, no clock unless ``issued`` is left out.

Decisions (each a FHIR choice a hospital integrator will ask about):

- **One resource.**  The route answers one resource, so the three Observations (one per knee angle) are
  ``contained`` and referenced as ``#flexion``, ``#adduction``, ``#internal-rotation`` (FHIR ids may not hold
  ``_``).  The patient (``patient_mode``, ``CHAKAMO_FHIR_PATIENT``) is either a contained ``#patient`` carrying the
  hospital's ``external_id`` (type ``MR`` of HL7 v2 table 0203, system ``patient_identifier_system`` when the
  hospital's MRN namespace is configured) and ChakaMo's id (system ``{base_url}/patients``), or — for a
  hospital that owns its Patient resources — a logical reference by that MR identifier, with nothing contained,
  or (``reference``) the hospital's own ``Patient/<id>`` given with the patient (``fhir_reference``) as
  ``subject.reference``.  :mod:`app.web.fhir_push` turns the report into a transaction Bundle for a FHIR server.
  The report carries ``id`` = the session id and the identifiers ``{base_url}/sessions`` | session id and, when
  the order gave one, its accession number (type ``ACSN``); ``basedOn`` names the order (a ServiceRequest
  reference) and ``encounter`` the visit, both as the hospital sent them with the session.
- **Both knees.**  A session of both knees (results.json ``knees``) adds one contained Observation per limb
  symmetry index parameter (``#lsi-swing-peak-flexion``...): the LSI in % as ``valueQuantity``, the involved and
  uninvolved knees' values as components, ``bodySite`` the involved knee; the three angle Observations stay those
  of the top-level (involved) knee.
- **Codes.**  Category: HL7 v2 table 0074 ``PT`` "Physical Therapy" (report) and observation-category
  ``exam`` (observations: range of motion is a physical-examination finding).  No LOINC code is emitted, after
  looking (2026-12, through the loinc.org term pages and HL7 implementation guides' value sets at hand): LOINC's
  range-of-motion terms found are CMS assessment items, not angles — 92850-7 / 92851-5 "Range of motion during
  assessment period [CMS Assessment] Upper / Lower extremity" (HL7 PACIO Personal Functioning and Engagement IG,
  ValueSet pfe-neuromusculoskeletal-vs) — and its older per-joint passive/active ROM terms (class H&P.PX) are
  deprecated; for gait, the terms found are of other methods and quantities — 83172-7 "4-Meter Walk Gait Speed
  Test - computed score [NIH Toolbox]" (m/s, a timed walk; https://loinc.org/83144-6) and 41956-4 "Walking speed
  24 hour maximum" — while ChakaMo measures no walking speed, and no LOINC term for cadence during an instrumented
  gait or for a knee angle over a motor-task cycle was found.  So report, observation, component and
  method codes come from ChakaMo's own code system, :data:`CODE_SYSTEM` (a UUID URN: unique without owning a
  domain) or ``CHAKAMO_FHIR_CODE_SYSTEM``; the codes are part of the interface: never change one.
- **Body site and laterality** (SNOMED CT): 49076000 |Knee joint structure| refined by the attribute
  272741003 |Laterality| = 24028007 |Right| or 7771000 |Left| as a post-coordinated expression
  (``49076000:272741003=24028007``; FHIR allows SNOMED CT expressions in ``Coding.code``), plus the plain
  knee-joint code for receivers that cannot read expressions, and the text "Right knee joint".  The side
  is ``results["side"]``: the knee that was measured (the patient record's side may name the other).
- **Numbers.**  Each Observation has no ``value[x]`` but components: ROM maximum, minimum and range
  over a cycle, mean and SD (ddof = 1) over the accepted cycles, as UCUM ``deg`` quantities rounded to
  :data:`DECIMALS` (0.1°, as the reports print them); a value that is ``null`` there (SD of a single cycle) gets
  ``dataAbsentReason`` ``not-applicable``.  The accepted and detected cycle counts (``valueInteger``),
  the orientation filter and the angle convention (``valueString``) are components too: they belong to
  the measurement, and a machine can read them.  Method: ChakaMo's ``imu-thigh-shank``.  When the task's
  reference (``results.json`` ``reference``, :mod:`estimators.motor_task.reference`) flags the flexion range, its
  range-mean component carries ``interpretation`` (HL7 v3 ObservationInterpretation L / N / H) and the band as
  ``referenceRange``.
- **Texts.**  ``conclusion`` summarises side, task, cycles and the clinical quality warnings in the PDF's
  language (``language`` says which; warnings translated by :func:`reports.warning_text.warning_text`; the
  technical notes, :func:`reports.warning_text.is_technical`, are left out: results.json keeps them apart in
  ``quality.technical_notes``, and a results.json written before that has them filtered here); the session's notes follow.  R4 ``DiagnosticReport`` has no
  ``note`` element (R5 added it).  The narrative (``text``) repeats the table in XHTML.  The PDF goes in
  ``presentedForm`` with its language, translated title, size and SHA-1 hash (base64, as R4 defines).
- **Validation, twice.**  The dictionary is built by hand, then parsed by two maintained model
  packages, and any complaint raises :class:`FhirExportError`:  ``fhirclient`` (SMART on FHIR), whose
  models are generated from exactly FHIR 4.0.1 and reject unknown elements, missing required ones and
  wrong types; and ``fhir.resources``, whose pydantic models are stricter on primitives (id and instant
  patterns, one choice of ``[x]``) but exist only for R4B (4.3.0) and R5 since version 7, so its ``R4B``
  package is used.  Every element used here is identical in R4 and R4B.

References: FHIR R4 (4.0.1) DiagnosticReport, Observation, Attachment (``hash`` = base64 SHA-1) and
"Using SNOMED CT with FHIR" (concept ids and compositional-grammar expressions are valid codes);
HL7 v2 tables 0074 (``PT`` Physical Therapy) and 0203 (``MR``); SNOMED CT International Edition for
49076000, 272741003, 24028007 and 7771000 (the last two are the laterality value set of HL7 Europe's
base IG); UCUM ``deg``.  Measured on a 4-cycle demo session (this machine): 8.6 ms per report
(263 kB PDF, 364 kB JSON), 0.27 s to import this module.
"""

from __future__ import annotations

import base64
import hashlib
import html
import math
import re
from collections.abc import Mapping
from datetime import date, datetime, timezone
from typing import Any

import pydantic
from fhir.resources.R4B.bundle import Bundle as R4BBundle
from fhir.resources.R4B.capabilitystatement import CapabilityStatement as R4BCapabilityStatement
from fhir.resources.R4B.diagnosticreport import DiagnosticReport as R4BDiagnosticReport
from fhirclient.models.bundle import Bundle as R4Bundle
from fhirclient.models.capabilitystatement import CapabilityStatement as R4CapabilityStatement
from fhirclient.models.diagnosticreport import DiagnosticReport as R4DiagnosticReport
from fhirclient.models.fhirabstractbase import FHIRValidationError

from app.choices import TASKS
from estimators.motor_task import reference
from reports.i18n import LANGUAGES, t
from reports.warning_text import is_technical

#: ChakaMo's own code system (report, observation, component and method codes) unless
#: ``CHAKAMO_FHIR_CODE_SYSTEM`` names another: a UUID URN (RFC 4122 §3), globally unique without a domain, so it
#: can never resolve to someone else's, nor depend on the host ChakaMo runs on.  Stable: never change it or a code.
CODE_SYSTEM = "urn:uuid:ebd20665-cf32-4709-83d2-dabc9acf8b93"
#: decimals of the exported angles (the reports print one: sensor-based knee angles are not better than ~1°)
DECIMALS = 1
#: how the report names its patient: a contained Patient, a logical reference by the hospital's identifier, or
#: the hospital's own FHIR Patient (the patient's ``fhir_reference``; by identifier for a patient without one)
PATIENT_MODES = ("contained", "identifier", "reference")
#: a reference to the hospital's Patient: relative (``Patient/<id>``) or absolute
PATIENT_REFERENCE = re.compile(r"^(?:https?://\S+/)?Patient/[A-Za-z0-9\-.]{1,64}$")
_REFERENCE = re.compile(r"^(?:https?://\S+/)?(ServiceRequest|Encounter)/[A-Za-z0-9\-.]{1,64}$")
#: the conclusion and narrative's fixed words, per language (the warnings come from reports.warning_text)
_WORDS = {
    "en": {"side": {"right": "Right knee", "left": "Left knee"}, "cycles": "{a} of {d} detected cycles accepted",
           "filter": "orientation filter {f}", "warnings": "Quality warnings", "none": "none", "notes": "Session notes",
           "table": "angle (degrees, mean ± SD over cycles)", "max": "maximum", "min": "minimum", "range": "range",
           "patient": "patient"},
    "es": {"side": {"right": "Rodilla derecha", "left": "Rodilla izquierda"},
           "cycles": "{a} de {d} ciclos detectados aceptados", "filter": "filtro de orientación {f}",
           "warnings": "Avisos de calidad", "none": "ninguno", "notes": "Notas de la sesión",
           "table": "ángulo (grados, media ± DE entre ciclos)", "max": "máximo", "min": "mínimo", "range": "rango",
           "patient": "paciente"},
    "pt": {"side": {"right": "Joelho direito", "left": "Joelho esquerdo"},
           "cycles": "{a} de {d} ciclos detectados aceitos", "filter": "filtro de orientação {f}",
           "warnings": "Avisos de qualidade", "none": "nenhum", "notes": "Notas da sessão",
           "table": "ângulo (graus, média ± DP entre ciclos)", "max": "máximo", "min": "mínimo", "range": "amplitude",
           "patient": "paciente"},
}
SNOMED = "http://snomed.info/sct"
UCUM = "http://unitsofmeasure.org"
V2_0074 = "http://terminology.hl7.org/CodeSystem/v2-0074"
V2_0203 = "http://terminology.hl7.org/CodeSystem/v2-0203"
OBSERVATION_CATEGORY = "http://terminology.hl7.org/CodeSystem/observation-category"
DATA_ABSENT_REASON = "http://terminology.hl7.org/CodeSystem/data-absent-reason"
INTERPRETATION = "http://terminology.hl7.org/CodeSystem/v3-ObservationInterpretation"
_INTERPRETATION_TEXT = {"L": "Low", "N": "Normal", "H": "High"}

#: SNOMED CT: 49076000 |Knee joint structure|, 272741003 |Laterality|, 24028007 |Right|, 7771000 |Left|
KNEE_JOINT = ("49076000", "Knee joint structure")
LATERALITY_ATTRIBUTE = "272741003"
LATERALITY = {"right": ("24028007", "Right"), "left": ("7771000", "Left")}

ANGLES = ("flexion", "adduction", "internal_rotation")
ROM_STATS = ("max", "min", "range")
_ANGLE_TEXT = {"flexion": "Knee flexion (+) / extension angle",
               "adduction": "Knee adduction (varus, +) / abduction angle",
               "internal_rotation": "Knee internal (+) / external rotation angle"}
_STAT_TEXT = {"max": "maximum", "min": "minimum", "range": "range of motion (maximum - minimum)"}
_TASK_TEXT = {t.name: t.label.lower() for t in TASKS}  # the motor-task registry's labels (app.choices)
_CONVENTION_TEXT = {"grood_suntay": "Grood & Suntay joint coordinate system, left leg mirrored",
                    "thesis_zyx": "ZYX Euler angles of the calibrated knee quaternion (thesis-compatible)"}
_GENDER = {"male": "male", "m": "male", "female": "female", "f": "female", "other": "other", "unknown": "unknown"}
_FHIR_ID = re.compile(r"[A-Za-z0-9\-.]{1,64}")

SESSION_KEYS = ("id", "date", "task", "professional", "notes", "created_at")
PATIENT_KEYS = ("id", "external_id", "side", "name", "birth_date", "sex")


class FhirExportError(ValueError):
    """The input cannot be exported (the message says what and how to fix it), or the result is not FHIR R4;
    ``code``: the catalogue code of a refusal a clinic's user causes and can mend (``app.web.messages``, es/en/pt:
    the FHIR push's trail shows it), None for one only a developer or the operator can."""

    def __init__(self, message: str, code: str | None = None) -> None:
        super().__init__(message)
        self.code = code


def diagnostic_report(*, session: dict, patient: dict, results: dict, pdf: bytes, lang: str, base_url: str,
                      issued: datetime | None = None, patient_identifier_system: str | None = None,
                      code_system: str = CODE_SYSTEM, patient_mode: str = "contained",
                      accession_system: str | None = None) -> dict:
    """The FHIR R4 ``DiagnosticReport`` of one processed knee session, as a JSON-ready dict (validated).

    session : ``{"id", "date", "task", "professional", "notes", "created_at"}``; ``date`` (ISO string,
        ``date`` or ``datetime``; ``created_at`` when it is None) becomes ``effectiveDateTime``.
    patient : ``{"id", "external_id", "side", "name", "birth_date", "sex"}``; ``sex`` one of male, female,
        other, unknown, m, f (any case) or None; may hold ``fhir_reference`` (the hospital's ``Patient/<id>``).
    results : the session's ``results.json`` as a dict (DESIGN §4).
    pdf : the clinical report in ``lang`` (es, en or pt), put in ``presentedForm``.
    base_url : the namespace of the session and patient identifiers (an absolute URI: ``CHAKAMO_PUBLIC_URL``/api/v1
        or ``CHAKAMO_FHIR_IDENTIFIER_BASE``; never the request's host).
    issued : when the report was released (timezone-aware; default: now, UTC, whole seconds).
    patient_identifier_system : the URI of the hospital's namespace of ``external_id`` when known.
    code_system : the URI of ChakaMo's code system (default :data:`CODE_SYSTEM`).
    patient_mode : ``contained`` (a Patient inside the report), ``identifier`` (``subject`` is a logical
        reference by the hospital's record number: needs ``patient_identifier_system``) or ``reference``
        (``subject.reference`` is the patient's ``fhir_reference``; by identifier for a patient without one).
    session may also hold ``service_request`` and ``encounter`` (FHIR references, ``basedOn`` and ``encounter``)
    and ``accession`` (an identifier of type ACSN, in ``accession_system`` when given).

    Raises :class:`FhirExportError` (a ``ValueError``) naming the missing or malformed input.
    """
    for name, value, keys in (("session", session, SESSION_KEYS), ("patient", patient, PATIENT_KEYS)):
        if not isinstance(value, Mapping):
            raise FhirExportError(f"{name} must be a dict with the keys {', '.join(keys)}, got {type(value).__name__}")
        missing = [k for k in keys if k not in value]
        if missing:
            raise FhirExportError(f"{name} is missing the key(s) {', '.join(missing)}; pass all of {', '.join(keys)} "
                                  "(None where unknown)")
    if lang not in LANGUAGES:
        raise FhirExportError(f"lang must be one of {', '.join(LANGUAGES)}, got {lang!r}")
    if not isinstance(pdf, (bytes, bytearray)) or not bytes(pdf[:5]) == b"%PDF-":
        raise FhirExportError("pdf must be the bytes of the PDF report (starting with %PDF-); render the report first")
    if not isinstance(base_url, str) or not re.fullmatch(r"https?://\S+", base_url):
        raise FhirExportError(f"base_url must be an absolute http(s) URL such as http://host/api/v1, got {base_url!r}")
    if patient_mode not in PATIENT_MODES:
        raise FhirExportError(f"patient_mode must be one of {', '.join(PATIENT_MODES)}, got {patient_mode!r}")
    reference = patient.get("fhir_reference") if patient_mode == "reference" else None
    if reference and not PATIENT_REFERENCE.fullmatch(str(reference)):
        raise FhirExportError(f"patient fhir_reference {reference!r} is not a FHIR reference such as Patient/123",
                              "fhir.patient_reference_invalid")
    if patient_mode != "contained" and not reference and (not patient_identifier_system or not patient["external_id"]):
        raise FhirExportError("the patient can be referred to by identifier only with a record number and "
                              "CHAKAMO_PATIENT_IDENTIFIER_SYSTEM set (or, with CHAKAMO_FHIR_PATIENT=reference, give "
                              "the patient its fhir_reference)", "fhir.patient_unreferenced")
    for key in ("service_request", "encounter"):
        ref = session.get(key)
        if ref and not _REFERENCE.fullmatch(str(ref)):
            raise FhirExportError(f"session {key} {ref!r} is not a FHIR reference such as "
                                  f"{'ServiceRequest' if key == 'service_request' else 'Encounter'}/123")
    base_url = base_url.rstrip("/")
    r = _results(results)
    report_id = _fhir_id(session["id"], "session id")
    effective = _date_time(session["date"] if session["date"] is not None else session["created_at"],
                           "session date (or created_at when the date is None)")
    issued_at = _instant(issued)
    side = r["side"]
    task = _TASK_TEXT.get(r["task"], str(r["task"]).replace("_", " "))
    professional = session["professional"] or None
    performer = [{"display": str(professional)}] if professional else None

    if patient_mode == "contained":
        contained_patient = [_patient(patient, base_url, patient_identifier_system)]
        subject = {"reference": "#patient"}
    elif reference:
        contained_patient = []
        subject = {"reference": str(reference), "type": "Patient"}
    else:
        contained_patient = []
        subject = {"type": "Patient", "identifier": _mr_identifier(patient, patient_identifier_system)}
    observations = [_observation(angle, r, side, task, effective, issued_at, performer, code_system, subject)
                    for angle in ANGLES]
    lsi = _lsi_observations(results.get("symmetry"), task, effective, issued_at, performer, code_system, subject)
    identifiers = [{"system": f"{base_url}/sessions", "value": str(session["id"])}]
    if session.get("accession"):
        identifiers.append({"use": "official", "system": accession_system,
                            "type": {"coding": [{"system": V2_0203, "code": "ACSN", "display": "Accession ID"}]},
                            "value": str(session["accession"])})
    doc: dict[str, Any] = {
        "resourceType": "DiagnosticReport",
        "id": report_id,
        "language": lang,  # the conclusion and narrative are in the PDF's language
        "text": {"status": "generated", "div": _narrative(r, side, task, effective, patient, lang, results)},
        "contained": [*contained_patient, *observations, *lsi],
        "identifier": identifiers,
        "basedOn": [{"reference": session["service_request"]}] if session.get("service_request") else None,
        "status": "final",
        "category": [{"coding": [{"system": V2_0074, "code": "PT", "display": "Physical Therapy"}]}],
        "code": {"coding": [_local("knee-kinematics-report", "Instrumented knee kinematics report", code_system)],
                 "text": f"Knee kinematics, {task}, two magneto-inertial sensors (thigh, shank)"},
        "subject": subject,
        "encounter": {"reference": session["encounter"]} if session.get("encounter") else None,
        "effectiveDateTime": effective,
        "issued": issued_at,
        "performer": performer,
        "result": [{"reference": f"#{obs['id']}", "display": _ANGLE_TEXT[a]} for a, obs in zip(ANGLES, observations)]
        + [{"reference": f"#{obs['id']}", "display": obs["code"]["coding"][0]["display"]} for obs in lsi],
        "conclusion": _conclusion(r, side, task, session["notes"], lang, results),
        "presentedForm": [{
            "contentType": "application/pdf",
            "language": lang,
            "data": base64.b64encode(bytes(pdf)).decode("ascii"),
            "size": len(pdf),
            "hash": base64.b64encode(hashlib.sha1(bytes(pdf)).digest()).decode("ascii"),
            "title": t("report_title", lang),
        }],
    }
    doc = _drop_none(doc)
    validate(doc)
    return doc


def _results(results: Any) -> dict[str, Any]:
    """The parts of results.json the export reads, checked (FhirExportError names the first bad key)."""
    def need(path: str) -> Any:
        node = results
        for key in path.split("."):
            if not isinstance(node, Mapping) or key not in node:
                raise FhirExportError(f"results is missing {path!r}; pass the session's results.json as written by "
                                      "chakamo process (reprocess the session if it predates this key)")
            node = node[key]
        return node

    if not isinstance(results, Mapping):
        raise FhirExportError(f"results must be the session's results.json as a dict, got {type(results).__name__}")
    side = need("side")
    if side not in LATERALITY:
        raise FhirExportError(f"results['side'] must be 'right' or 'left', got {side!r}")
    # results.json files written before "angle_method" existed hold Grood & Suntay angles
    out = {"side": side, "task": need("task"), "filter": need("filter.name"),
           "angle_method": results.get("angle_method", "grood_suntay"), "rom": {}}
    for key in ("detected", "accepted"):
        n = need(f"cycles.{key}")
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise FhirExportError(f"results['cycles']['{key}'] must be a count (int >= 0), got {n!r}")
        out[key] = n
    for angle in ANGLES:
        for stat in ROM_STATS:
            for m in ("mean", "sd"):
                path = f"rom_deg.{angle}.{stat}.{m}"
                out["rom"][(angle, stat, m)] = _number(need(path), path)
    # the reference's band of the flexion range (results.json "reference", issue 15 §3), when it flags one
    band = ((results.get("reference") or {}).get("parameters") or {}).get("flexion_rom_deg") or {}
    out["flexion_range_band"] = band if band.get("interpretation") in _INTERPRETATION_TEXT else None
    warnings = need("quality.warnings")
    if not isinstance(warnings, list) or not all(isinstance(w, Mapping) and "message" in w for w in warnings):
        raise FhirExportError("results['quality']['warnings'] must be a list of {'code', 'message'} objects")
    out["warnings"] = [dict(w) for w in warnings if not is_technical(w)]
    return out


def _number(x: Any, where: str) -> float | None:
    if x is None:
        return None
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise FhirExportError(f"results {where} must be a number or null, got {x!r}")
    return float(x) if math.isfinite(x) else None


def _fhir_id(value: Any, what: str) -> str:
    s = str(value)
    if value is None or not _FHIR_ID.fullmatch(s):
        raise FhirExportError(f"the {what} {value!r} cannot be a FHIR id (1-64 of A-Z a-z 0-9 - .)")
    return s


def _date_time(value: Any, what: str) -> str:
    """A FHIR dateTime: a date stays a date; a naive datetime is taken as UTC (the database stores UTC)."""
    if isinstance(value, str):
        try:
            value = date.fromisoformat(value) if len(value) == 10 else datetime.fromisoformat(value)
        except ValueError:
            raise FhirExportError(f"the {what} {value!r} is not an ISO date (YYYY-MM-DD) or date-time") from None
    if isinstance(value, datetime):
        if value.tzinfo is None:
            value = value.replace(tzinfo=timezone.utc)
        return value.isoformat()
    if isinstance(value, date):
        return value.isoformat()
    raise FhirExportError(f"the {what} is required: give an ISO date (YYYY-MM-DD), a date or a datetime, got {value!r}")


def _instant(value: datetime | None) -> str:
    if value is None:
        value = datetime.now(timezone.utc).replace(microsecond=0)
    if not isinstance(value, datetime) or value.tzinfo is None:
        raise FhirExportError(f"issued must be a timezone-aware datetime, got {value!r}")
    return value.isoformat()


def _local(code: str, display: str, system: str = CODE_SYSTEM) -> dict[str, str]:
    return {"system": system, "code": code, "display": display}


def _body_site(side: str) -> dict[str, Any]:
    knee, knee_display = KNEE_JOINT
    lat, lat_display = LATERALITY[side]
    return {"coding": [{"system": SNOMED, "code": f"{knee}:{LATERALITY_ATTRIBUTE}={lat}"},
                       {"system": SNOMED, "code": knee, "display": knee_display}],
            "text": f"{lat_display} knee joint"}


def _observation(angle: str, r: dict, side: str, task: str, effective: str, issued: str,
                 performer: list | None, system: str, subject: dict) -> dict[str, Any]:
    name = angle.replace("_", "-")
    components = []
    for stat in ROM_STATS:
        for m in ("mean", "sd"):
            what = "mean over the accepted cycles" if m == "mean" else "SD over the accepted cycles (ddof = 1)"
            code = _local(f"{stat}-{m}", f"{_STAT_TEXT[stat]} per cycle, {what}", system)
            comp: dict[str, Any] = {"code": {"coding": [code]}}
            value = r["rom"][(angle, stat, m)]
            if value is None:
                comp["dataAbsentReason"] = {"coding": [{"system": DATA_ABSENT_REASON, "code": "not-applicable",
                                                        "display": "Not Applicable"}]}
            else:
                comp["valueQuantity"] = {"value": round(value, DECIMALS), "unit": "deg", "system": UCUM, "code": "deg"}
            band = r["flexion_range_band"] if (angle, stat, m) == ("flexion", "range", "mean") else None
            if band and value is not None:  # v3 L/N/H against the reference's band, which goes beside it
                # on the numbers as exported: a reader comparing 60.0 with low 60.0 must see the flag we give
                # (59.96 against 60 is L in results.json, but reads 60.0 here: N)
                low, high = round(band["low"], DECIMALS), round(band["high"], DECIMALS)
                code = reference.interpretation(round(value, DECIMALS), reference.Band(low, high, "deg"))
                comp["interpretation"] = [{"coding": [{"system": INTERPRETATION, "code": code,
                                                       "display": _INTERPRETATION_TEXT[code]}]}]
                comp["referenceRange"] = [{"low": {"value": low, "unit": "deg", "system": UCUM, "code": "deg"},
                                           "high": {"value": high, "unit": "deg", "system": UCUM, "code": "deg"},
                                           "text": "results.json reference (ChakaMo), see the report"}]
            components.append(comp)
    components += [
        {"code": {"coding": [_local("cycles-accepted", "Motor-task cycles accepted", system)]},
         "valueInteger": r["accepted"]},
        {"code": {"coding": [_local("cycles-detected", "Motor-task cycles detected", system)]},
         "valueInteger": r["detected"]},
        {"code": {"coding": [_local("orientation-filter", "Orientation filter", system)]},
         "valueString": str(r["filter"])},
        {"code": {"coding": [_local("angle-convention", "Knee angle convention", system)]},
         "valueString": str(r["angle_method"])},
    ]
    convention = _CONVENTION_TEXT.get(r["angle_method"], str(r["angle_method"]))
    return {
        "resourceType": "Observation",
        "id": name,
        "status": "final",
        "category": [{"coding": [{"system": OBSERVATION_CATEGORY, "code": "exam", "display": "Exam"}]}],
        "code": {"coding": [_local(f"knee-{name}", _ANGLE_TEXT[angle], system)],
                 "text": f"{_ANGLE_TEXT[angle]} during {task}, degrees"},
        "subject": subject,
        "effectiveDateTime": effective,
        "issued": issued,
        "performer": performer,
        "bodySite": _body_site(side),
        "method": {"coding": [_local("imu-thigh-shank", "Two magneto-inertial measurement units, thigh and shank",
                                     system)],
                   "text": f"Two magneto-inertial sensors (thigh, shank), orientation filter {r['filter']!r}, "
                           f"{convention}"},
        "component": components,
    }


#: UCUM of the LSI parameters' units (results.json ``symmetry.parameters[].unit``)
_LSI_UCUM = {"deg": "deg", "pct": "%", "s": "s", "steps_min": "/min"}


def _lsi_observations(symmetry: Any, task: str, effective: str, issued: str, performer: list | None,
                      system: str, subject: dict) -> list[dict[str, Any]]:
    """A session of both knees: one Observation per limb symmetry index parameter (results.json ``symmetry``,
    :mod:`app.pipeline.knees`): ``valueQuantity`` the LSI in % (involved / uninvolved × 100), components the
    involved and uninvolved knees' values in the parameter's unit, ``bodySite`` the involved knee; an LSI that could
    not be computed has a ``dataAbsentReason``.  None for a one-knee session or without an involved side."""
    if not isinstance(symmetry, Mapping):
        return []
    out = []
    for p in symmetry.get("parameters", []):
        name = str(p["name"]).replace("_", "-")
        display = f"Limb symmetry index, {str(p['name']).replace('_', ' ')}"
        unit = _LSI_UCUM.get(p["unit"], "1")
        components = []
        for which in ("involved", "uninvolved"):
            comp: dict[str, Any] = {"code": {"coding": [_local(f"{which}-knee-value", f"{which.capitalize()} knee, "
                                                               "mean over its accepted cycles", system)]}}
            value = _number(p.get(which), f"symmetry {p['name']} {which}")
            if value is None:
                comp["dataAbsentReason"] = {"coding": [{"system": DATA_ABSENT_REASON, "code": "not-applicable",
                                                        "display": "Not Applicable"}]}
            else:
                comp["valueQuantity"] = {"value": round(value, DECIMALS), "unit": unit, "system": UCUM, "code": unit}
            components.append(comp)
        obs: dict[str, Any] = {
            "resourceType": "Observation", "id": f"lsi-{name}", "status": "final",
            "category": [{"coding": [{"system": OBSERVATION_CATEGORY, "code": "exam", "display": "Exam"}]}],
            "code": {"coding": [_local(f"lsi-{name}", display, system)],
                     "text": f"{display} during {task}: involved / uninvolved × 100 %"},
            "subject": subject, "effectiveDateTime": effective, "issued": issued,
            "performer": performer, "bodySite": _body_site(symmetry["involved"]), "component": components,
        }
        lsi = _number(p.get("lsi_pct"), f"symmetry {p['name']} lsi_pct")
        if lsi is None:
            obs["dataAbsentReason"] = {"coding": [{"system": DATA_ABSENT_REASON, "code": "not-applicable",
                                                   "display": "Not Applicable"}]}
        else:
            obs["valueQuantity"] = {"value": round(lsi, DECIMALS), "unit": "%", "system": UCUM, "code": "%"}
        out.append(obs)
    return out


def _mr_identifier(patient: Mapping, identifier_system: str | None) -> dict[str, Any]:
    """The hospital's record number as a FHIR Identifier (type MR, in ``identifier_system`` when known)."""
    return {"use": "usual", "system": identifier_system,
            "type": {"coding": [{"system": V2_0203, "code": "MR", "display": "Medical record number"}]},
            "value": str(patient["external_id"])}


def _patient(patient: Mapping, base_url: str, identifier_system: str | None) -> dict[str, Any]:
    identifiers = []
    if patient["external_id"] not in (None, ""):
        identifiers.append(_mr_identifier(patient, identifier_system))
    if patient["id"] is not None:
        identifiers.append({"use": "secondary", "system": f"{base_url}/patients", "value": str(patient["id"])})
    sex = patient["sex"]
    gender = None
    if sex not in (None, ""):
        gender = _GENDER.get(str(sex).strip().lower())
        if gender is None:
            raise FhirExportError(f"patient sex {sex!r} is not one of male, female, other, unknown (or m, f); "
                                  "fix the patient record")
    birth = patient["birth_date"]
    if birth not in (None, ""):
        birth = _date_time(birth, "patient birth_date")[:10]
    return {"resourceType": "Patient", "id": "patient", "identifier": identifiers or None,
            "name": [{"text": str(patient["name"])}] if patient["name"] else None,
            "gender": gender, "birthDate": birth or None}


def _warning_lines(r: dict, lang: str, results: Mapping) -> list[str]:
    """The clinical quality warnings in ``lang`` (technical notes left out: :func:`reports.warning_text.is_technical`)."""
    from reports.warning_text import warning_text

    return [warning_text(w, lang, results)[0] for w in r["warnings"]]


def _conclusion(r: dict, side: str, task: str, notes: Any, lang: str = "en", results: Mapping | None = None) -> str:
    """Side, task, cycles, filter, the clinical warnings and the session's notes, in ``lang`` (the task's name
    stays English: the motor-task registry's label)."""
    w = _WORDS[lang]
    text = (f"{w['side'][side]}, {task}: {w['cycles'].format(a=r['accepted'], d=r['detected'])}; "
            f"{w['filter'].format(f=repr(r['filter']))}. ")
    lines = _warning_lines(r, lang, results or {})
    if lines:
        text += f"{w['warnings']} ({len(lines)}): " + "; ".join(lines) + "."
    else:
        text += f"{w['warnings']}: {w['none']}."
    if notes:
        text += f" {w['notes']}: {notes}"
    return text


def _narrative(r: dict, side: str, task: str, effective: str, patient: Mapping, lang: str = "en",
               results: Mapping | None = None) -> str:
    esc = html.escape
    w = _WORDS[lang]

    def cell(angle: str, stat: str) -> str:
        mean, sd = r["rom"][(angle, stat, "mean")], r["rom"][(angle, stat, "sd")]
        if mean is None:
            return "—"
        return f"{mean:.1f}" if sd is None else f"{mean:.1f} ± {sd:.1f}"

    rows = "".join(f"<tr><td>{esc(_ANGLE_TEXT[a])}</td>" + "".join(f"<td>{cell(a, s)}</td>" for s in ROM_STATS)
                   + "</tr>" for a in ANGLES)
    who = esc(str(patient["external_id"] or patient["id"]))
    warnings = "".join(f"<li>{esc(m)}</li>" for m in _warning_lines(r, lang, results or {})) or \
        f"<li>{w['none']}</li>"
    return ('<div xmlns="http://www.w3.org/1999/xhtml">'
            f"<p>{esc(w['side'][side])}, {esc(task)}; {w['patient']} {who}; {esc(effective)}. "
            f"{esc(w['cycles'].format(a=r['accepted'], d=r['detected']))}, "
            f"{esc(w['filter'].format(f=r['filter']))}.</p>"
            f"<table><tr><th>{esc(w['table'])}</th><th>{w['max']}</th><th>{w['min']}</th>"
            f"<th>{w['range']}</th></tr>{rows}</table><p>{esc(w['warnings'])}:</p><ul>{warnings}</ul></div>")


def _drop_none(x: Any) -> Any:
    """``x`` without None values and empty lists (FHIR forbids ``null`` and empty arrays)."""
    if isinstance(x, dict):
        return {k: _drop_none(v) for k, v in x.items() if v is not None and v != []}
    if isinstance(x, list):
        return [_drop_none(v) for v in x]
    return x


def search_bundle(reports: list[dict]) -> dict:
    """A FHIR R4 ``searchset`` Bundle of ``reports`` (DiagnosticReports of :func:`diagnostic_report`), validated
    with both model packages."""
    doc = {"resourceType": "Bundle", "type": "searchset", "total": len(reports),
           "entry": [{"resource": r, "search": {"mode": "match"}} for r in reports]}
    doc = _drop_none(doc)
    _validate_with(doc, R4Bundle, R4BBundle)
    return doc


def capability_statement(*, software_version: str, server_url: str | None, date_time: datetime | None = None
                         ) -> dict:
    """The CapabilityStatement of ``GET /fhir/metadata``: FHIR 4.0.1, JSON, DiagnosticReport read and search by
    ``patient`` (validated with both model packages); ``server_url``: this server's FHIR address (None: unknown)."""
    doc = {"resourceType": "CapabilityStatement", "status": "active", "kind": "instance",
           "date": _instant(date_time), "fhirVersion": "4.0.1", "format": ["application/fhir+json"],
           "software": {"name": "ChakaMo", "version": software_version},
           "implementation": {"description": "ChakaMo knee kinematics: DiagnosticReport export",
                              "url": server_url},
           "rest": [{"mode": "server",
                     "security": {"description": "Authorization: Bearer <token> (chakamo tokens create)"},
                     "resource": [{"type": "DiagnosticReport",
                                   "interaction": [{"code": "read"}, {"code": "search-type"}],
                                   "searchParam": [{"name": "patient", "type": "reference",
                                                    "documentation": "the patient's ChakaMo id (123 or Patient/123)"}]}
                                  ]}]}
    doc = _drop_none(doc)
    _validate_with(doc, R4CapabilityStatement, R4BCapabilityStatement)
    return doc


def validate_bundle(doc: dict) -> None:
    """Check that ``doc`` is a valid FHIR R4 ``Bundle`` with both model packages (:class:`FhirExportError`)."""
    _validate_with(doc, R4Bundle, R4BBundle)


def _validate_with(doc: dict, r4_model, r4b_model) -> None:
    try:
        r4_model(doc, strict=True)
    except FHIRValidationError as exc:
        raise FhirExportError(f"{doc['resourceType']} is not valid FHIR R4 (4.0.1, fhirclient): {exc}") from None
    try:
        r4b_model.model_validate(doc)
    except pydantic.ValidationError as exc:
        raise FhirExportError(f"{doc['resourceType']} fails FHIR validation (fhir.resources R4B): {exc}") from None


def validate(doc: dict) -> None:
    """Check that ``doc`` is a valid FHIR R4 ``DiagnosticReport`` with both model packages (module docstring).

    Raises :class:`FhirExportError` quoting the packages' complaints (for :func:`diagnostic_report`'s
    output that is a ChakaMo bug: report it with the session).
    """
    try:
        R4DiagnosticReport(doc, strict=True)
    except FHIRValidationError as exc:
        raise FhirExportError(f"DiagnosticReport {doc.get('id')!r} is not valid FHIR R4 (4.0.1, fhirclient): "
                              f"{exc}") from None
    try:
        R4BDiagnosticReport.model_validate(doc)
    except pydantic.ValidationError as exc:
        raise FhirExportError(f"DiagnosticReport {doc.get('id')!r} fails FHIR validation (fhir.resources R4B): "
                              f"{exc}") from None
