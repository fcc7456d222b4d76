"""Settings of the web application (environment variables, read once through :func:`get_settings`).

| variable | default | what |
| --- | --- | --- |
| ``CHAKAMO_ENV`` | ``production`` | ``development`` allows the insecure conveniences below; ``production`` refuses them |
| ``CHAKAMO_DATA_DIR`` | the per-user data dir (platformdirs) | database, blobs (uploads and artefacts), temporary files |
| ``DATABASE_URL`` | ``sqlite:///<data_dir>/chakamo.db`` | any SQLAlchemy URL (PostgreSQL needs its driver installed) |
| ``CHAKAMO_SECRET_KEY`` | none | keys the CSRF tokens; required (≥ 32 characters) outside development |
| ``CHAKAMO_JOB_BACKEND`` | ``inprocess`` | ``inprocess``: worker threads inside ``chakamo serve``; ``celery``: Celery workers (``chakamo worker``) fed through the broker |
| ``CHAKAMO_BROKER_URL`` | ``redis://127.0.0.1:6379/0`` | the Celery broker (Redis), with ``celery`` |
| ``CHAKAMO_WORKERS`` | 2 | processing threads of the embedded pool; the default concurrency of ``chakamo worker`` |
| ``CHAKAMO_JOB_LEASE_S`` | 60 | a running job whose worker has not beaten its heartbeat for this long is taken as lost and queued again |
| ``CHAKAMO_REDISPATCH_S`` | 120 | celery: a job still queued this long after it was handed to the broker, while the broker's queue is empty, is handed again (a broker restarted empty) |
| ``CHAKAMO_JOB_TIME_LIMIT_S`` | 1800 | celery: a job running longer is stopped (its worker process is replaced) and run again, then failed after 3 attempts |
| ``CHAKAMO_BROKER_VISIBILITY_TIMEOUT_S`` | 3600 | Redis: an unacknowledged message (its worker died) is delivered again after this long |
| ``CHAKAMO_RENDER_PROCESSES`` | 1 | with any (≥ 1): each embedded job thread computes and renders its jobs in a warm helper process of its own at background priority (:mod:`app.jobs.compute`), and the API server checks uploads in ``CHAKAMO_CHECK_PROCESSES`` warm helper processes, both off its GIL (0: none, both in the server's threads) |
| ``CHAKAMO_CHECK_PROCESSES`` | 2 | with render processes: helper processes checking uploads, one clinic's check at a time each (:mod:`app.store.checks`) |
| ``CHAKAMO_MAX_FILE_MB`` | 50 | largest uploaded file |
| ``CHAKAMO_MAX_FILES`` | 40 | most files per upload request and per session |
| ``CHAKAMO_MAX_BODY_KB`` | 1024 | largest request body of any route but the recordings upload (413 above it, :mod:`app.web.limits`) |
| ``CHAKAMO_MAX_UPLOADS`` | 8 | uploads streamed at the same time (more answer 503: try again) |
| ``CHAKAMO_SESSION_HOURS`` | 12 | browser login lifetime |
| ``CHAKAMO_RETENTION_DAYS`` | 0 (off) | sessions with no activity for this many days are erased with their files (``chakamo retention``, :mod:`app.store.retention`) |
| ``CHAKAMO_PUBLIC_URL`` | none | this server's address as its users reach it (``https://chakamo.hospital.example``): the namespace of the FHIR identifiers, never taken from a request's ``Host`` in production |
| ``CHAKAMO_ALLOWED_HOSTS`` | ``*`` | comma-separated host names a request's ``Host`` may name (``*.example.org`` for subdomains); others answer 400 (``/healthz``, ``/readyz`` excepted); ``*`` any |
| ``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM`` | none | URI of the hospital's record-number namespace: the FHIR MR identifier's system and ``GET /patients?identifier=system|value`` |
| ``CHAKAMO_FHIR_IDENTIFIER_BASE`` | ``CHAKAMO_PUBLIC_URL``/api/v1 | namespace of ChakaMo's FHIR identifier systems (``<base>/sessions``, ``<base>/patients``): an http(s) address (a ``urn:`` is refused at start-up) |
| ``CHAKAMO_FHIR_CODE_SYSTEM`` | ChakaMo's ``urn:uuid:`` code system | URI of the code system of the exported codes |
| ``CHAKAMO_FHIR_PATIENT`` | ``contained`` | ``identifier``: the DiagnosticReport names its patient by the MR identifier instead of containing it; ``reference``: by the hospital's own FHIR Patient (the patient's ``fhir_reference``, else by identifier) |
| ``CHAKAMO_FHIR_PUSH_URL`` | none (no push) | the base of a hospital FHIR R4 server: every finished job's report is POSTed there as a transaction Bundle, retried like a webhook (:mod:`app.web.fhir_push`) |
| ``CHAKAMO_FHIR_PUSH_CLINICS`` | none | comma-separated names of the clinics whose reports are pushed (each clinic opts in; one taken off stops its pushes, its trail kept); with ``CHAKAMO_PATIENT_IDENTIFIER_SYSTEM`` set, one clinic only (record numbers are matched in that one namespace: :mod:`app.web.fhir_push`) |
| ``CHAKAMO_FHIR_PUSH_TOKEN`` | none | sent as ``Authorization: Bearer <token>`` with each push |
| ``CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS`` | none | the host names the push may reach, with the webhooks' rules (:mod:`app.web.webhooks`): an internal address only when its name is listed exactly; the push URL's host must match it |
| ``CHAKAMO_ACCESSION_SYSTEM`` | none | URI of the namespace of the sessions' accession numbers |
| ``CHAKAMO_WEBHOOK_ALLOWED_HOSTS`` | none (webhooks refused) | comma-separated host names a webhook URL may name (``*.hospital.example`` for subdomains, ``*`` any); a name resolving to a loopback, private, link-local or multicast address is refused at send time unless named exactly here (:mod:`app.web.webhooks`) |
| ``CHAKAMO_WEBHOOK_RETRY_S`` | 10 | first webhook retry's wait, doubling each time (:mod:`app.web.webhooks`) |

A refusal is a :class:`SettingsError` of a code of :data:`MESSAGES` (es/en/pt; ``str()`` English, ``chakamo``
prints it in ``--lang``); pydantic's own refusals (a bound, not a number, not a choice) are said of their variable.

Decisions: the default environment is ``production`` so that a forgotten variable fails safe; a
missing or short secret key is then a clear start-up error of the server (the command line's set-up commands
use no key and do not ask for one: :func:`get_settings` ``require_key=False``; ``development`` uses a fixed, publicly known
key and drops the cookie's ``Secure`` flag so plain-http localhost works).  Settings are never created at
import time: :func:`get_settings` builds them on first use and caches them; tests pass their own
:class:`Settings` to :func:`app.web.main.create_app`.
"""

from __future__ import annotations

import re
import typing
from contextvars import ContextVar
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, ValidationInfo, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

#: the development key: public, so refused outside development
DEV_SECRET_KEY = "chakamo-development-key-not-secret-do-not-use-in-production"
#: file types an upload may carry: CSV (MetaBase, generic, Xsens, Shimmer, phyphox), Excel (thesis, phyphox), zip (Sensor
#: Logger, phyphox; read within app.pipeline.ingestion.phyphox's zip caps), APDM Opal .h5 (read within
#: app.pipeline.ingestion.opal's declared-size caps; any other HDF5 is refused by the check as opal.not_apdm) and
#: session.json
ALLOWED_SUFFIXES = (".csv", ".xlsx", ".json", ".zip", ".h5")


#: every refusal of the environment, in es/en/pt: ``MESSAGES[code][lang]`` is a :meth:`str.format` template of the
#: :class:`SettingsError`'s params; each names the variable and says what to set.  The CLI catalogue
#: (:data:`app.web.messages.CATALOGUE`) holds this table too, so the consistency tests read it; it lives here
#: because the settings sit below everything that could render it (``tests/test_architecture.py``).
MESSAGES: dict[str, dict[str, str]] = {
    "settings.public_url": {
        "en": "CHAKAMO_PUBLIC_URL={value!r} is not an http(s) address; set it to the address users reach this server "
              "at, e.g. https://chakamo.hospital.example",
        "es": "CHAKAMO_PUBLIC_URL={value!r} no es una dirección http(s); defínala como la dirección con la que los "
              "usuarios llegan a este servidor, p. ej. https://chakamo.hospital.example",
        "pt": "CHAKAMO_PUBLIC_URL={value!r} não é um endereço http(s); defina-a com o endereço pelo qual os "
              "utilizadores chegam a este servidor, p. ex. https://chakamo.hospital.example"},
    "settings.not_a_uri": {
        "en": "{var}={value!r} is not a URI; give e.g. urn:oid:1.2.3 or https://hospital.example/mrn, or unset it",
        "es": "{var}={value!r} no es un URI; indique p. ej. urn:oid:1.2.3 o https://hospital.example/mrn, o "
              "elimine la variable",
        "pt": "{var}={value!r} não é um URI; indique p. ex. urn:oid:1.2.3 ou https://hospital.example/mrn, ou "
              "elimine a variável"},
    "settings.identifier_base": {
        "en": "CHAKAMO_FHIR_IDENTIFIER_BASE={value!r} is not an http(s) address: the identifier systems are "
              "<base>/sessions and <base>/patients, which a urn: cannot be extended into; give e.g. "
              "https://chakamo.hospital.example/api/v1, or leave it unset (CHAKAMO_PUBLIC_URL/api/v1)",
        "es": "CHAKAMO_FHIR_IDENTIFIER_BASE={value!r} no es una dirección http(s): los sistemas de identificadores "
              "son <base>/sessions y <base>/patients, que no pueden añadirse a un urn:; indique p. ej. "
              "https://chakamo.hospital.example/api/v1, o no la defina (CHAKAMO_PUBLIC_URL/api/v1)",
        "pt": "CHAKAMO_FHIR_IDENTIFIER_BASE={value!r} não é um endereço http(s): os sistemas de identificadores são "
              "<base>/sessions e <base>/patients, que não se podem acrescentar a um urn:; indique p. ex. "
              "https://chakamo.hospital.example/api/v1, ou não a defina (CHAKAMO_PUBLIC_URL/api/v1)"},
    "settings.push_url": {
        "en": "CHAKAMO_FHIR_PUSH_URL={value!r} is not an http(s) address; give the FHIR server's base, e.g. "
              "https://fhir.hospital.example/fhir",
        "es": "CHAKAMO_FHIR_PUSH_URL={value!r} no es una dirección http(s); indique la base del servidor FHIR, p. ej. "
              "https://fhir.hospital.example/fhir",
        "pt": "CHAKAMO_FHIR_PUSH_URL={value!r} não é um endereço http(s); indique a base do servidor FHIR, p. ex. "
              "https://fhir.hospital.example/fhir"},
    "settings.push_https": {
        "en": "CHAKAMO_FHIR_PUSH_URL={value!r} must be https outside development (the reports carry patient data); "
              "give the FHIR server's https:// address",
        "es": "CHAKAMO_FHIR_PUSH_URL={value!r} debe ser https fuera de desarrollo (los informes llevan datos de "
              "pacientes); indique la dirección https:// del servidor FHIR",
        "pt": "CHAKAMO_FHIR_PUSH_URL={value!r} tem de ser https fora de desenvolvimento (os relatórios contêm dados "
              "de doentes); indique o endereço https:// do servidor FHIR"},
    "settings.broker_url": {
        "en": "CHAKAMO_BROKER_URL={value!r} is not a Redis URL; set it to redis://HOST:6379/0 (the broker the Celery "
              "workers read)",
        "es": "CHAKAMO_BROKER_URL={value!r} no es una URL de Redis; defínala como redis://HOST:6379/0 (el "
              "intermediario que leen los trabajadores de Celery)",
        "pt": "CHAKAMO_BROKER_URL={value!r} não é um URL do Redis; defina-o como redis://HOST:6379/0 (o "
              "intermediário que os trabalhadores do Celery leem)"},
    "settings.no_secret_key": {
        "en": "CHAKAMO_SECRET_KEY is not set; set it to a long random string (e.g. the output of "
              "`python -c \"import secrets; print(secrets.token_urlsafe(48))\"`), or set CHAKAMO_ENV=development "
              "for a local trial",
        "es": "CHAKAMO_SECRET_KEY no está definida; defínala como una cadena aleatoria larga (p. ej. la salida de "
              "`python -c \"import secrets; print(secrets.token_urlsafe(48))\"`), o defina CHAKAMO_ENV=development "
              "para una prueba local",
        "pt": "CHAKAMO_SECRET_KEY não está definida; defina-a como uma cadeia aleatória longa (p. ex. o resultado de "
              "`python -c \"import secrets; print(secrets.token_urlsafe(48))\"`), ou defina CHAKAMO_ENV=development "
              "para um ensaio local"},
    "settings.weak_secret_key": {
        "en": "CHAKAMO_SECRET_KEY is too weak (the development key, or shorter than {min} characters); set a long "
              "random string",
        "es": "CHAKAMO_SECRET_KEY es demasiado débil (la clave de desarrollo, o de menos de {min} caracteres); "
              "defina una cadena aleatoria larga",
        "pt": "CHAKAMO_SECRET_KEY é demasiado fraca (a chave de desenvolvimento, ou com menos de {min} caracteres); "
              "defina uma cadeia aleatória longa"},
    # pydantic's own refusals of a variable (its English sentence names no variable), by kind
    "settings.at_least": {
        "en": "{var}={value!r} is too small; set it to {limit} or more, or unset it for the default",
        "es": "{var}={value!r} es demasiado pequeño; defínalo en {limit} o más, o elimínelo para usar el valor por "
              "defecto",
        "pt": "{var}={value!r} é demasiado pequeno; defina-o com {limit} ou mais, ou elimine-o para usar o valor "
              "predefinido"},
    "settings.more_than": {
        "en": "{var}={value!r} is too small; set it to more than {limit}, or unset it for the default",
        "es": "{var}={value!r} es demasiado pequeño; defínalo en más de {limit}, o elimínelo para usar el valor por "
              "defecto",
        "pt": "{var}={value!r} é demasiado pequeno; defina-o com mais de {limit}, ou elimine-o para usar o valor "
              "predefinido"},
    "settings.at_most": {
        "en": "{var}={value!r} is too large; set it to {limit} or less, or unset it for the default",
        "es": "{var}={value!r} es demasiado grande; defínalo en {limit} o menos, o elimínelo para usar el valor por "
              "defecto",
        "pt": "{var}={value!r} é demasiado grande; defina-o com {limit} ou menos, ou elimine-o para usar o valor "
              "predefinido"},
    "settings.not_an_integer": {
        "en": "{var}={value!r} is not a whole number; give one such as 2, or unset it for the default",
        "es": "{var}={value!r} no es un número entero; indique uno como 2, o elimínelo para usar el valor por "
              "defecto",
        "pt": "{var}={value!r} não é um número inteiro; indique um como 2, ou elimine-o para usar o valor "
              "predefinido"},
    "settings.not_a_number": {
        "en": "{var}={value!r} is not a number; give one such as 2.5 (a point before the decimals), or unset it for "
              "the default",
        "es": "{var}={value!r} no es un número; indique uno como 2.5 (con punto antes de los decimales), o elimínelo "
              "para usar el valor por defecto",
        "pt": "{var}={value!r} não é um número; indique um como 2.5 (com ponto antes das casas decimais), ou "
              "elimine-o para usar o valor predefinido"},
    "settings.not_a_choice": {
        "en": "{var}={value!r} is not one of {choices}; set one of them, or unset it for the default",
        "es": "{var}={value!r} no es ninguno de {choices}; defina uno de ellos, o elimínelo para usar el valor por "
              "defecto",
        "pt": "{var}={value!r} não é nenhum de {choices}; defina um deles, ou elimine-o para usar o valor "
              "predefinido"},
    "settings.invalid": {
        "en": "{var}={value!r} cannot be used ({detail}); correct it, or unset it for the default",
        "es": "{var}={value!r} no se puede usar ({detail}); corríjalo, o elimínelo para usar el valor por defecto",
        "pt": "{var}={value!r} não pode ser usado ({detail}); corrija-o, ou elimine-o para usar o valor "
              "predefinido"},
}

#: the shortest ``CHAKAMO_SECRET_KEY`` accepted outside development
MIN_KEY_CHARS = 32


class SettingsError(ValueError):
    """The environment asks for something unsafe or unavailable: ``SettingsError(code, **params)``, entry ``code``
    of :data:`MESSAGES`; ``str()`` is English (logs, programs), :meth:`message` any of es/en/pt (``chakamo``
    prints it in ``--lang``: :func:`app.cli.main.main`).  :attr:`parts` holds one ``(code, params)`` per refusal
    (several when pydantic found several: :func:`get_settings`).  A ``code`` that is no entry of :data:`MESSAGES` is
    taken as an English sentence of its own (the FHIR push's start-up refusals, :mod:`app.web.fhir_push`)."""

    def __init__(self, code: str, /, **params) -> None:
        self.code, self.params = code, params
        self.parts: tuple[tuple[str, dict], ...] = ((code, params),)
        super().__init__(self.message("en"))

    @classmethod
    def joined(cls, parts: list[tuple[str, dict]]) -> "SettingsError":
        """One error of several refusals (their sentences joined by "; ")."""
        error = cls(parts[0][0], **parts[0][1])
        error.parts = tuple(parts)
        error.args = (error.message("en"),)
        return error

    def message(self, lang: str) -> str:
        """The sentences of :attr:`parts` in ``lang`` (English for a language not in :data:`MESSAGES`)."""
        return "; ".join(_render(code, params, lang) for code, params in self.parts)


def _render(code: str, params: dict, lang: str) -> str:
    texts = MESSAGES.get(code)
    return code if texts is None else texts.get(lang, texts["en"]).format(**params)


def _default_data_dir() -> Path:
    from platformdirs import user_data_dir

    return Path(user_data_dir("chakamo", appauthor=False))


def _names(text: str) -> tuple[str, ...]:
    """A comma-separated list of host names (or patterns) as lower-case names, blanks dropped."""
    return tuple(h.strip().lower() for h in text.split(",") if h.strip())


class Settings(BaseSettings):
    """Validated settings (see the module docstring for the variables and defaults)."""

    model_config = SettingsConfigDict(extra="ignore", populate_by_name=True)

    env: Literal["development", "production"] = Field("production", validation_alias="CHAKAMO_ENV")
    data_dir: Path = Field(default_factory=_default_data_dir, validation_alias="CHAKAMO_DATA_DIR")
    database_url: str | None = Field(None, validation_alias="DATABASE_URL")
    secret_key: str | None = Field(None, validation_alias="CHAKAMO_SECRET_KEY")
    job_backend: Literal["inprocess", "celery"] = Field("inprocess", validation_alias="CHAKAMO_JOB_BACKEND")
    broker_url: str = Field("redis://127.0.0.1:6379/0", validation_alias="CHAKAMO_BROKER_URL")
    workers: int = Field(2, ge=1, le=64, validation_alias="CHAKAMO_WORKERS")
    job_lease_s: float = Field(60.0, ge=2.0, le=3600.0, validation_alias="CHAKAMO_JOB_LEASE_S")
    redispatch_s: float = Field(120.0, ge=1.0, le=86400.0, validation_alias="CHAKAMO_REDISPATCH_S")
    job_time_limit_s: float = Field(1800.0, ge=10.0, validation_alias="CHAKAMO_JOB_TIME_LIMIT_S")
    broker_visibility_timeout_s: float = Field(3600.0, ge=5.0, validation_alias="CHAKAMO_BROKER_VISIBILITY_TIMEOUT_S")
    render_processes: int = Field(1, ge=0, le=16, validation_alias="CHAKAMO_RENDER_PROCESSES")
    check_processes: int = Field(2, ge=0, le=16, validation_alias="CHAKAMO_CHECK_PROCESSES")
    max_file_mb: float = Field(50.0, gt=0, validation_alias="CHAKAMO_MAX_FILE_MB")
    max_files: int = Field(40, ge=1, validation_alias="CHAKAMO_MAX_FILES")
    max_body_kb: int = Field(1024, ge=16, validation_alias="CHAKAMO_MAX_BODY_KB")
    max_uploads: int = Field(8, ge=1, le=256, validation_alias="CHAKAMO_MAX_UPLOADS")
    session_hours: float = Field(12.0, gt=0, validation_alias="CHAKAMO_SESSION_HOURS")
    retention_days: int = Field(0, ge=0, le=36500, validation_alias="CHAKAMO_RETENTION_DAYS")
    public_url: str | None = Field(None, validation_alias="CHAKAMO_PUBLIC_URL")
    allowed_hosts: str = Field("*", validation_alias="CHAKAMO_ALLOWED_HOSTS")
    #: the URI of the hospital's namespace of patients' record numbers (``external_id``), e.g.
    #: ``urn:oid:2.16.840.1.113883.2.9.4.3.2`` or ``https://hospital.example/mrn``: the FHIR identifier's system
    #: and the system of ``GET /patients?identifier=system|value``; None: not known (identifiers carry none)
    patient_identifier_system: str | None = Field(None, validation_alias="CHAKAMO_PATIENT_IDENTIFIER_SYSTEM")
    #: the namespace of ChakaMo's own FHIR identifier systems (``<base>/sessions``, ``<base>/patients``); None:
    #: ``CHAKAMO_PUBLIC_URL``/api/v1.  Never built from a request's Host.
    fhir_identifier_base: str | None = Field(None, validation_alias="CHAKAMO_FHIR_IDENTIFIER_BASE")
    #: the URI of ChakaMo's FHIR code system; None: the product's own (``app.web.fhir.CODE_SYSTEM``)
    fhir_code_system: str | None = Field(None, validation_alias="CHAKAMO_FHIR_CODE_SYSTEM")
    #: how a DiagnosticReport names its patient: ``contained`` (a Patient inside it) or ``identifier`` (a logical
    #: reference by the record number in CHAKAMO_PATIENT_IDENTIFIER_SYSTEM, for a hospital that owns the Patient)
    fhir_patient: Literal["contained", "identifier", "reference"] = Field("contained",
                                                                         validation_alias="CHAKAMO_FHIR_PATIENT")
    #: the base URL of the hospital's FHIR server the reports are pushed to (``app.web.fhir_push``); None: no push
    fhir_push_url: str | None = Field(None, validation_alias="CHAKAMO_FHIR_PUSH_URL")
    #: the names of the clinics whose reports are pushed, comma-separated (each opts in; ``app.web.fhir_push``)
    fhir_push_clinics: str = Field("", validation_alias="CHAKAMO_FHIR_PUSH_CLINICS")
    #: the bearer token of that server (never stored in the database)
    fhir_push_token: str | None = Field(None, validation_alias="CHAKAMO_FHIR_PUSH_TOKEN")
    #: the host names the push may reach (the webhooks' rules)
    fhir_push_allowed_hosts: str = Field("", validation_alias="CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS")
    #: the URI of the namespace of the sessions' accession numbers (the ordering system's), when known
    accession_system: str | None = Field(None, validation_alias="CHAKAMO_ACCESSION_SYSTEM")
    #: the first webhook retry's wait; each next one doubles it (``app.web.webhooks``)
    webhook_retry_s: float = Field(10.0, gt=0, le=3600, validation_alias="CHAKAMO_WEBHOOK_RETRY_S")
    #: the host names webhook URLs may name (``app.web.webhooks``); empty: webhooks are refused
    webhook_allowed_hosts: str = Field("", validation_alias="CHAKAMO_WEBHOOK_ALLOWED_HOSTS")
    allowed_suffixes: tuple[str, ...] = ALLOWED_SUFFIXES

    @field_validator("env", "job_backend", mode="before")
    @classmethod
    def _lower(cls, value: object) -> object:
        return value.strip().lower() if isinstance(value, str) else value

    @field_validator("public_url", mode="after")
    @classmethod
    def _public_url(cls, value: str | None) -> str | None:
        if value is None or not value.strip():
            return None
        value = value.strip().rstrip("/")
        if not re.fullmatch(r"https?://[A-Za-z0-9.\-\[\]:]+(/[\w.\-~/]*)?", value):
            raise SettingsError("settings.public_url", value=value)
        return value

    @field_validator("patient_identifier_system", "fhir_identifier_base", "fhir_code_system", "accession_system",
                     mode="after")
    @classmethod
    def _identifier_system(cls, value: str | None, info: ValidationInfo) -> str | None:
        if value is None or not value.strip():
            return None
        value = value.strip()
        if not re.fullmatch(r"(urn:[a-z0-9][a-z0-9-]*:\S+|https?://\S+)", value, flags=re.IGNORECASE) or "|" in value:
            raise SettingsError("settings.not_a_uri", var=_variable(info.field_name), value=value)
        return value

    @field_validator("fhir_identifier_base", mode="after")
    @classmethod
    def _identifier_base(cls, value: str | None) -> str | None:
        if value is not None and not re.match(r"https?://", value, flags=re.IGNORECASE):
            raise SettingsError("settings.identifier_base", value=value)
        return value

    @property
    def host_patterns(self) -> tuple[str, ...]:
        """:data:`allowed_hosts` as lower-case names (``("*",)``: any)."""
        return _names(self.allowed_hosts) or ("*",)

    @field_validator("fhir_push_url", mode="after")
    @classmethod
    def _push_url(cls, value: str | None) -> str | None:
        if value is None or not value.strip():
            return None
        value = value.strip().rstrip("/")
        if not re.fullmatch(r"https?://[A-Za-z0-9.\-\[\]:]+(/[\w.\-~/]*)?", value):
            raise SettingsError("settings.push_url", value=value)
        return value

    @property
    def fhir_push_host_patterns(self) -> tuple[str, ...]:
        """:data:`fhir_push_allowed_hosts` as lower-case names (empty: none allowed)."""
        return _names(self.fhir_push_allowed_hosts)

    @property
    def fhir_push_clinic_names(self) -> tuple[str, ...]:
        """:data:`fhir_push_clinics` as names (as the clinics are named, blanks and repeats dropped)."""
        return tuple(dict.fromkeys(n.strip() for n in self.fhir_push_clinics.split(",") if n.strip()))

    @property
    def sealing_key(self) -> bytes | None:
        """The key stored secrets are sealed under (:mod:`app.store.sealed`): ``CHAKAMO_SECRET_KEY``, the development
        key in development, None when no key is set in production (a command that needs none)."""
        return self.key if self.secret_key or self.development else None

    @property
    def webhook_host_patterns(self) -> tuple[str, ...]:
        """:data:`webhook_allowed_hosts` as lower-case names (empty: none allowed)."""
        return _names(self.webhook_allowed_hosts)

    @model_validator(mode="after")
    def _refuse_insecure(self) -> "Settings":
        if self.job_backend == "celery" and not self.broker_url.startswith(("redis://", "rediss://")):
            raise SettingsError("settings.broker_url", value=self.broker_url)
        if self.fhir_push_url:  # its host is checked against CHAKAMO_FHIR_PUSH_ALLOWED_HOSTS by app.web.fhir_push
            if not self.development and not self.fhir_push_url.lower().startswith("https://"):
                raise SettingsError("settings.push_https", value=self.fhir_push_url)
        if self.env == "production" and _KEY_NEEDED.get():
            if not self.secret_key:
                raise SettingsError("settings.no_secret_key")
            if len(self.secret_key) < MIN_KEY_CHARS or self.secret_key == DEV_SECRET_KEY:
                raise SettingsError("settings.weak_secret_key", min=MIN_KEY_CHARS)
        return self

    @property
    def development(self) -> bool:
        return self.env == "development"

    @property
    def key(self) -> bytes:
        """The secret key as bytes (the development key in development when none is set)."""
        return (self.secret_key or DEV_SECRET_KEY).encode()

    @property
    def db_url(self) -> str:
        return self.database_url or f"sqlite:///{(self.data_dir / 'chakamo.db').as_posix()}"

    @property
    def blob_dir(self) -> Path:
        return self.data_dir / "blobs"

    @property
    def tmp_dir(self) -> Path:
        return self.data_dir / "tmp"

    @property
    def max_file_bytes(self) -> int:
        return int(self.max_file_mb * 1024 * 1024)


def _variable(field: str | None) -> str:
    """The environment variable of field ``field`` (its validation alias)."""
    info = Settings.model_fields.get(field or "")
    return str(info.validation_alias) if info is not None and info.validation_alias else str(field)


#: pydantic's error types -> the :data:`MESSAGES` entry saying the same of a variable, and the bound it names
_PYDANTIC = {"greater_than_equal": ("settings.at_least", "ge"), "greater_than": ("settings.more_than", "gt"),
             "less_than_equal": ("settings.at_most", "le"),
             "int_parsing": ("settings.not_an_integer", None), "int_from_float": ("settings.not_an_integer", None),
             "float_parsing": ("settings.not_a_number", None), "literal_error": ("settings.not_a_choice", None)}


def _parts(error: dict) -> list[tuple[str, dict]]:
    """The ``(code, params)`` of one of pydantic's errors: our own refusal's parts, or its kind said of the variable
    its ``loc`` names (the variable's value shown, but never a secret's)."""
    own = error.get("ctx", {}).get("error")
    if isinstance(own, SettingsError):
        return list(own.parts)
    var = str(error["loc"][0]) if error.get("loc") else "?"
    value = "***" if ("SECRET" in var or "TOKEN" in var) else error.get("input")
    code, bound = _PYDANTIC.get(error["type"], ("settings.invalid", None))
    if code == "settings.not_a_choice":
        field = next((f for f, i in Settings.model_fields.items() if i.validation_alias == var), None)
        options = typing.get_args(Settings.model_fields[field].annotation) if field else ()
        return [(code, {"var": var, "value": value, "choices": ", ".join(map(str, options)) or "?"})]
    if code == "settings.invalid":
        return [(code, {"var": var, "value": value, "detail": error.get("msg", "")})]
    params = {"var": var, "value": value}
    if bound:
        params["limit"] = error.get("ctx", {}).get(bound)
    return [(code, params)]


#: False while settings are read for a command that uses no secret key (:func:`get_settings`)
_KEY_NEEDED: ContextVar[bool] = ContextVar("chakamo_key_needed", default=True)


@lru_cache(maxsize=2)
def get_settings(require_key: bool = True) -> Settings:
    """The process' settings from the environment, built once (raises :class:`SettingsError` if unsafe).
    ``require_key=False`` for commands that never use ``CHAKAMO_SECRET_KEY`` (the command line's clinics, users,
    tokens and records: the key only signs the browsers' CSRF tokens), which then run without it in production."""
    token = _KEY_NEEDED.set(require_key)
    try:
        return Settings()
    except SettingsError:
        raise
    except ValidationError as exc:  # pydantic's error wraps our SettingsErrors and its own: one sentence each
        raise SettingsError.joined([part for e in exc.errors() for part in _parts(e)]) from None
    finally:
        _KEY_NEEDED.reset(token)


__all__ = ["ALLOWED_SUFFIXES", "DEV_SECRET_KEY", "MESSAGES", "MIN_KEY_CHARS", "Settings", "SettingsError",
           "get_settings"]
