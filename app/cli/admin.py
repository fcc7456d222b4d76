"""Set-up commands of the web application (``chakamo serve``, ``clinics``, ``users``, ``tokens``).

``chakamo serve [--host 127.0.0.1] [--port 8000] [--proxy-headers --forwarded-allow-ips IPS] [--lang es|en|pt]``
    The web application on the embedded default (SQLite, local files, in-process jobs) under
    ``CHAKAMO_DATA_DIR``; loopback unless ``--host`` says otherwise.  Behind a reverse proxy (TLS),
    ``--proxy-headers`` takes the client address and scheme from the proxy's ``X-Forwarded-*`` headers, trusted
    only from ``--forwarded-allow-ips`` (default: loopback) — so the per-address login limit and the audit log
    see the browser's address, not the proxy's.
``chakamo clinics create NAME``
    A new clinic (tenant).
``chakamo users create --clinic NAME --email E --role admin|clinician|read_only [--name N] [--password-stdin]``
    A user; the password is asked twice without echo, or read from the first line of stdin with
    ``--password-stdin`` (for scripts).  There is never a default password.
``chakamo tokens create --clinic NAME [--label L] [--role clinician|read_only|admin] [--expires-days N]
[--scope resource:read|write ...]``
    An API token for a hospital system; printed once, alone on the last line of the output (only its
    sha256 is stored, so it cannot be shown again).  Optionally it expires (401 afterwards) and is limited to
    scopes within its role (403 outside them; :mod:`app.store.tokens`).
``chakamo tokens rotate ID [--grace-hours 24]``
    A successor token (same clinic, label, role, scopes and lifetime), printed once on the last line; the old
    one keeps working for the grace period, then answers 401.
``chakamo tokens list --clinic NAME`` / ``chakamo tokens revoke ID``
    The clinic's API tokens (id, label, role, created, revoked, expires, scopes; never the token), and revocation: the API
    then answers 401 to it.  Revoking a revoked token changes nothing, so offboarding scripts can run twice.
``chakamo users deactivate --email E``
    Logins refused, and the user's browser sessions deleted, so an open browser is logged out at its next
    request rather than when its cookie expires.
``chakamo users set-password --email E [--password-stdin]``
    A new password (same rules as ``users create``); the user's browser sessions are deleted too (a reset
    after a suspected leak must close the sessions opened with the old password); ``active`` is unchanged.

The commands use the same settings as the server (``CHAKAMO_DATA_DIR``, ``DATABASE_URL``...), apply the
migrations first, and raise ``ValueError`` with one sentence for anything the user can fix (the CLI prints
it and exits with status 2).  The functions are importable for tests and scripts: their first argument is a
:class:`~app.settings.Settings` (``None``: the environment's).
"""

from __future__ import annotations

import argparse
import getpass
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from app.choices import LANGUAGE_NAMES
from app.choices import USER_ROLE_NAMES as ROLES  # the one definition of the roles (cheap to import)

if TYPE_CHECKING:  # the database stack is imported on use: `chakamo demo` does not pay for it
    from sqlalchemy.orm import Session

    from app.store.database import Database
    from app.settings import Settings

COMMANDS = ("serve", "clinics", "users", "tokens")


def _head_revision() -> str | None:
    """The newest migration's revision id, read from the files of ``app/store/migrations/versions`` (the one
    revision no other names as its ``down_revision``), without importing alembic; None when that is not one."""
    import re

    from app.store.database import MIGRATIONS_DIR

    revisions, downs = set(), set()
    for path in (MIGRATIONS_DIR / "versions").glob("*.py"):
        text = path.read_text(encoding="utf-8")
        rev = re.search(r"^revision\s*=\s*['\"]([^'\"]+)['\"]", text, re.MULTILINE)
        down = re.search(r"^down_revision\s*=\s*['\"]([^'\"]+)['\"]", text, re.MULTILINE)
        if rev:
            revisions.add(rev.group(1))
        if down:
            downs.add(down.group(1))
    heads = revisions - downs
    return next(iter(heads)) if len(heads) == 1 else None


def _database(settings: Settings | None) -> Database:
    """The settings' database, migrated.  A database already at the newest revision is not handed to alembic:
    importing it costs a set-up command about a third of its start (``benchmarks/cli_setup.py``)."""
    from sqlalchemy import Column, MetaData, String, Table, select

    from app.store.database import Database
    from app.settings import get_settings

    settings = settings or get_settings(require_key=False)  # set-up commands never use the secret key
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    db = Database(settings.db_url)
    try:
        with db.engine.connect() as conn:
            version = Table("alembic_version", MetaData(), Column("version_num", String(32)))  # alembic's table
            current = conn.execute(select(version.c.version_num)).scalars().all()
    except Exception:  # noqa: BLE001 — a new database (no table yet): alembic creates everything
        current = []
    if current != [_head_revision()]:
        db.migrate(settings.sealing_key)
    return db


@contextmanager
def _session(settings: Settings | None) -> Iterator[Session]:
    """A session of the migrated database of ``settings``, committed on success; the engine is disposed after."""
    db = _database(settings)
    try:
        with db.session() as s:
            yield s
    finally:
        db.dispose()


class CliError(ValueError):
    """A refusal of these commands: ``code`` of a catalogue (:func:`app.web.refusals.catalogue_of`: the accounts'
    ``cli.*`` entries, or a domain error's) and its ``params``; ``str()`` is English, :meth:`message` any
    language (``chakamo`` prints it in ``--lang``: :func:`app.cli.main.main`)."""

    def __init__(self, code: str, **params) -> None:
        self.code, self.params = code, params
        super().__init__(self.message("en"))

    def message(self, lang: str) -> str:
        from app.pipeline.ingestion.messages import render
        from app.web.refusals import catalogue_of

        return render(self.code, self.params, lang, catalogue_of(self.code))


def _say(lang: str | None, code: str, **params) -> str:
    """Sentence ``code`` of :data:`app.web.messages.CATALOGUE` in ``lang`` (``--lang``; English when not given)."""
    from app.cli.language import say

    return say(code, lang or "en", **params)


def _clinic(s, name: str):
    """Clinic ``name`` (:func:`app.store.accounts.clinic_named`: ``store.clinic_unknown`` when there is none)."""
    from app.store.accounts import clinic_named

    return clinic_named(s, name)


def create_clinic(settings: Settings | None, name: str) -> int:
    """Create clinic ``name``; returns its id.  :class:`CliError` if the name is empty or taken."""
    name = name.strip()
    if not name:
        raise CliError("cli.clinic_name_empty")
    from sqlalchemy import select

    from app.store.models import Clinic

    with _session(settings) as s:
        if s.scalar(select(Clinic.id).where(Clinic.name == name)) is not None:
            raise CliError("cli.clinic_exists", name=name)
        clinic = Clinic(name=name)
        s.add(clinic)
        s.flush()
        return clinic.id


def create_user(settings: Settings | None, *, clinic: str, email: str, role: str, password: str,
                name: str = "") -> int:
    """Create a user of clinic ``clinic``; returns the id.  :class:`CliError` (a ValueError) for a bad role, weak
    password or an email that already has an account in that clinic (accounts are per clinic: the same email may
    have an account in another clinic)."""
    if role not in ROLES:
        raise CliError("cli.role_unknown", role=role, roles=", ".join(ROLES))
    email = email.strip().lower()
    if "@" not in email or len(email) < 3:
        raise CliError("cli.email_invalid", email=email)
    from app.store import accounts
    from app.store.errors import DomainError
    from app.web.audit import record_operator
    from app.web.security import hash_password

    _strong(password, email=email, name=name)
    with _session(settings) as s:
        c = _clinic(s, clinic)
        try:  # the API's own insert: the taken-email check and the unique constraint's race
            user = accounts.add_user(s, c.id, email=email, name=name, role=role, password_hash=hash_password(password))
        except DomainError:  # the operator is told which clinic (an admin in the API is not: finding 10b)
            raise CliError("cli.email_taken", email=email, clinic=clinic) from None
        record_operator(s, clinic_id=c.id, action="user_create", user_id=user.id,
                        detail=f"user {user.id} role {role}")
        return user.id


def create_token(settings: Settings | None, *, clinic: str, label: str = "", role: str = "clinician",
                 expires_days: float | None = None, scopes: list[str] | None = None) -> str:
    """Create an API token of clinic ``clinic`` and return it (the only time it exists in clear); ``expires_days``:
    refused that many days from now (None: never); ``scopes``: :data:`app.choices.TOKEN_SCOPES` it may use
    within its role (None: all)."""
    if role not in ROLES:
        raise CliError("cli.role_unknown", role=role, roles=", ".join(ROLES))
    from app.store import tokens
    from app.web.audit import record_operator
    from app.web.security import new_token, sha256_hex

    token = new_token()
    with _session(settings) as s:
        c = _clinic(s, clinic)
        row = tokens.add_token(s, c.id, token_sha256=sha256_hex(token), role=role, label=label,
                               expires_days=expires_days, scopes=scopes)
        record_operator(s, clinic_id=c.id, action="token_create", token_id=row.id,
                        detail=f"token {row.id} role {role}" + (f" ({label})" if label else "")
                        + (f" scopes {row.scopes}" if row.scopes else "")
                        + (f" expires {row.expires_at:%Y-%m-%d}" if row.expires_at else ""))
    return token


def rotate_token(settings: Settings | None, token_id: int, *, grace_hours: float = 24.0) -> tuple[str, dict]:
    """A successor of API token ``token_id`` (same clinic, label, role, scopes, lifetime) and the old one ending
    ``grace_hours`` from now: ``(new token, {"id", "new_id", "clinic", "old_expires_at", "expires_at"})``."""
    from app.store import tokens
    from app.web.audit import record_operator
    from app.web.security import new_token, sha256_hex

    token = new_token()
    with _session(settings) as s:
        old, new = tokens.rotate_token(s, token_id, sha256_hex(token), grace_hours=grace_hours)
        record_operator(s, clinic_id=old.clinic_id, action="token_rotate", token_id=new.id,
                        detail=f"token {new.id} replaces token {old.id} (ends {old.expires_at:%Y-%m-%d %H:%M} UTC)")
        info = {"id": old.id, "new_id": new.id, "clinic": old.clinic.name, "old_expires_at": old.expires_at,
                "expires_at": new.expires_at}
    return token, info


def serve(host: str = "127.0.0.1", port: int = 8000, proxy_headers: bool = False,
          forwarded_allow_ips: str = "127.0.0.1", lang: str | None = None) -> None:
    """Run the web application with uvicorn until interrupted (its start-up line in ``lang``, English when None)."""
    import uvicorn

    from app.web.main import UVICORN_OPTIONS, create_app
    from app.settings import get_settings

    settings = get_settings()  # errors (e.g. no secret key) before anything starts
    print(_say(lang, "cli.serve_started", host=host, port=port, data_dir=settings.data_dir), file=sys.stderr)
    uvicorn.run(create_app(settings, lang=lang), host=host, port=port, log_level="info", proxy_headers=proxy_headers,
                forwarded_allow_ips=forwarded_allow_ips if proxy_headers else None, **UVICORN_OPTIONS)


def add_parsers(sub) -> None:
    """Register ``serve``, ``clinics``, ``users`` and ``tokens`` on the ``chakamo`` subparsers."""
    serve_p = sub.add_parser("serve", help="run the web application (embedded default: SQLite, local files)")
    serve_p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    serve_p.add_argument("--port", type=int, default=8000, help="port (default: 8000)")
    serve_p.add_argument("--proxy-headers", action="store_true",
                         help="behind a reverse proxy: trust its X-Forwarded-For/-Proto headers")
    serve_p.add_argument("--forwarded-allow-ips", default="127.0.0.1", metavar="IPS",
                         help="addresses of the proxies whose headers are trusted (default: 127.0.0.1)")
    serve_p.add_argument("--lang", choices=LANGUAGE_NAMES, default=None,
                         help="language of the messages (default: English)")

    clinics = sub.add_parser("clinics", help="manage clinics (tenants)").add_subparsers(dest="action", required=True)
    c_create = clinics.add_parser("create", help="create a clinic")
    c_create.add_argument("name", metavar="NAME")

    users = sub.add_parser("users", help="manage user accounts").add_subparsers(dest="action", required=True)
    u_create = users.add_parser("create", help="create a user (the password is asked for)")
    u_create.add_argument("--clinic", required=True, metavar="NAME")
    u_create.add_argument("--email", required=True)
    u_create.add_argument("--role", required=True, choices=ROLES)
    u_create.add_argument("--name", default="", help="full name shown in the UI")
    u_create.add_argument("--password-stdin", action="store_true", help="read the password from stdin's first line")

    tokens = sub.add_parser("tokens", help="manage API tokens").add_subparsers(dest="action", required=True)
    t_create = tokens.add_parser("create", help="create an API token (printed once)")
    t_create.add_argument("--clinic", required=True, metavar="NAME")
    t_create.add_argument("--label", default="", help="what the token is for, e.g. the hospital system")
    t_create.add_argument("--role", default="clinician", choices=ROLES, help="(default: clinician)")
    t_create.add_argument("--expires-days", type=float, default=None, metavar="N",
                          help="refused N days from now (default: never; a year is a sound choice)")
    t_create.add_argument("--scope", action="append", default=None, metavar="SCOPE",
                          help="what it may touch within its role, repeatable: resource:read|write, e.g. "
                               "patients:write fhir:read (default: everything the role allows)")
    t_rotate = tokens.add_parser("rotate", help="replace an API token: a new one (printed once), the old one ends "
                                                "after a grace period")
    t_rotate.add_argument("token_id", type=int, metavar="ID", help="the token's id (see `chakamo tokens list`)")
    t_rotate.add_argument("--grace-hours", type=float, default=24.0, metavar="H",
                          help="hours the old token keeps working (default 24; 0: ends now)")
    _add_account_parsers(users, tokens)
    for parser in (*clinics.choices.values(), *users.choices.values(), *tokens.choices.values()):
        parser.add_argument("--lang", choices=LANGUAGE_NAMES, default=None,   # their output and errors in --lang
                            help="language of the messages (default: English)")


def _read_password(from_stdin: bool, lang: str | None = None) -> str:
    if from_stdin:
        return sys.stdin.readline().rstrip("\r\n")
    from app.web.passwords import MIN_PASSWORD_LENGTH

    first = getpass.getpass(_say(lang, "cli.password_prompt", min=MIN_PASSWORD_LENGTH))
    if getpass.getpass(_say(lang, "cli.password_repeat")) != first:
        raise CliError("cli.passwords_differ")
    return first


def _strong(password: str, *, email: str, name: str) -> None:
    """The web application's password rules (:func:`app.web.security.check_password_strength`), refused as a
    :class:`CliError` of the rule's own catalogue entry (printed in ``--lang``)."""
    from app.web.passwords import WeakPassword
    from app.web.security import check_password_strength

    try:
        check_password_strength(password, email=email, name=name)
    except WeakPassword as exc:
        raise CliError(exc.code, **exc.params) from None


def run(args: argparse.Namespace) -> int:
    """Carry out a parsed ``serve`` / ``clinics`` / ``users`` / ``tokens`` command."""
    if args.command == "serve":
        serve(args.host, args.port, args.proxy_headers, args.forwarded_allow_ips, args.lang)
    elif args.command == "clinics":
        clinic_id = create_clinic(None, args.name)
        print(_say(args.lang, "cli.clinic_created", name=args.name.strip(), id=clinic_id))
    elif args.command == "users" and args.action == "create":
        password = _read_password(args.password_stdin, args.lang)
        user_id = create_user(None, clinic=args.clinic, email=args.email, role=args.role, password=password,
                              name=args.name)
        print(_say(args.lang, "cli.user_created", email=args.email.strip().lower(), role=args.role,
                   clinic=args.clinic, id=user_id))
    elif args.command == "tokens" and args.action == "create":
        token = create_token(None, clinic=args.clinic, label=args.label, role=args.role,
                             expires_days=args.expires_days, scopes=args.scope)
        details = [args.role] + ([args.label] if args.label else []) \
            + ([_say(args.lang, "cli.token_scopes", scopes=" ".join(args.scope))] if args.scope else []) \
            + ([_say(args.lang, "cli.token_expires", days=args.expires_days)] if args.expires_days else [])
        print(_say(args.lang, "cli.token_created", clinic=args.clinic, details=", ".join(details)))
        print(token)
    elif args.command == "tokens" and args.action == "rotate":
        token, info = rotate_token(None, args.token_id, grace_hours=args.grace_hours)
        print(_say(args.lang, "cli.token_rotated", new_id=info["new_id"], clinic=info["clinic"], id=info["id"],
                   ends=_when(info["old_expires_at"])))
        print(token)
    else:
        return run_account(args)
    return 0


__all__ = ["COMMANDS", "add_parsers", "create_clinic", "create_token", "create_user", "rotate_token", "run", "serve"]


# ------------------------------------------------------------------------------------------ offboarding


def _user(s, email: str, clinic: str | None = None):
    """The account of ``email`` in clinic ``clinic``, or its only account when no clinic is given; ValueError
    for none, and for an email with accounts in several clinics and no clinic given (it names them)."""
    from sqlalchemy import select

    from app.store.models import User

    email = email.strip().lower()
    stmt = select(User).where(User.email == email)
    if clinic is not None:
        stmt = stmt.where(User.clinic_id == _clinic(s, clinic).id)
    users = list(s.scalars(stmt.order_by(User.id)))
    if not users:
        if clinic is not None:
            raise CliError("cli.user_unknown_in", email=email, clinic=clinic)
        raise CliError("cli.user_unknown", email=email)
    if len(users) > 1:
        raise CliError("cli.user_ambiguous", email=email, clinics=", ".join(repr(u.clinic.name) for u in users))
    return users[0]


def _close_browser_sessions(s, user_id: int) -> int:
    from sqlalchemy import delete

    from app.store.models import BrowserSession

    return s.execute(delete(BrowserSession).where(BrowserSession.user_id == user_id)).rowcount or 0


def list_tokens(settings: Settings | None, *, clinic: str) -> list[dict]:
    """The API tokens of clinic ``clinic``, oldest first, as dicts ``id, label, role, created_at, revoked_at``
    (datetimes in UTC; ``revoked_at`` None while the token works).  Never the token itself."""
    from app.store import tokens

    with _session(settings) as s:
        c = _clinic(s, clinic)
        return [{"id": t.id, "label": t.label, "role": t.role, "created_at": t.created_at,
                 "revoked_at": t.revoked_at, "expires_at": t.expires_at, "scopes": t.scopes}
                for t in tokens.clinic_tokens(s, c.id)]


def revoke_token(settings: Settings | None, token_id: int) -> dict:
    """Revoke API token ``token_id`` (any clinic); returns ``id, clinic, label, revoked_at, already`` where
    ``already`` is True when it had been revoked before (its first date is kept).  ValueError for an
    unknown id."""
    from app.store import tokens
    from app.store.models import ApiToken
    from app.web.audit import record_operator

    with _session(settings) as s:
        token = s.get(ApiToken, token_id)
        if token is None:
            raise CliError("cli.token_unknown", id=token_id)
        already = not tokens.revoke(token)
        if not already:
            record_operator(s, clinic_id=token.clinic_id, action="token_revoke", token_id=token.id,
                            detail=f"token {token.id} revoked")
        return {"id": token.id, "clinic": token.clinic.name, "label": token.label,
                "revoked_at": token.revoked_at, "already": already}


def deactivate_user(settings: Settings | None, *, email: str, clinic: str | None = None) -> int:
    """Deactivate the user with ``email`` (of clinic ``clinic`` when the email has accounts in several; login
    refused) and delete their browser sessions; returns how many sessions were closed.  ValueError for an
    unknown email, or an ambiguous one without ``clinic``."""
    from app.web.audit import record_operator

    with _session(settings) as s:
        user = _user(s, email, clinic)
        user.active = False
        closed = _close_browser_sessions(s, user.id)
        record_operator(s, clinic_id=user.clinic_id, action="user_change", user_id=user.id,
                        detail=f"user {user.id}: deactivated, {closed} session(s) ended")
        return closed


def set_password(settings: Settings | None, *, email: str, password: str, clinic: str | None = None) -> int:
    """Give the user with ``email`` (of clinic ``clinic`` when the email has accounts in several) a new
    ``password`` (the rules of ``users create``: app.web.passwords) and delete their browser sessions; returns how
    many were closed.  ValueError for an unknown email, an ambiguous one without ``clinic``, or a weak password
    (nothing changes)."""
    from app.web.audit import record_operator
    from app.web.security import hash_password

    with _session(settings) as s:
        user = _user(s, email, clinic)
        _strong(password, email=user.email, name=user.name)
        user.password_hash = hash_password(password)
        closed = _close_browser_sessions(s, user.id)
        record_operator(s, clinic_id=user.clinic_id, action="password_change", user_id=user.id,
                        detail=f"set by the operator; {closed} session(s) ended")
        return closed


def _add_account_parsers(users, tokens) -> None:
    """``tokens list|revoke`` and ``users deactivate|set-password`` on :func:`add_parsers`' sub-parsers."""
    t_list = tokens.add_parser("list", help="list a clinic's API tokens (never the tokens themselves)")
    t_list.add_argument("--clinic", required=True, metavar="NAME")
    t_revoke = tokens.add_parser("revoke", help="revoke an API token: the API answers 401 to it")
    t_revoke.add_argument("token_id", type=int, metavar="ID", help="the token's id (see `chakamo tokens list`)")

    u_off = users.add_parser("deactivate", help="refuse a user's logins and log out their browsers")
    u_off.add_argument("--email", required=True)
    u_off.add_argument("--clinic", metavar="NAME", help="the account's clinic (needed when the email has several)")
    u_pw = users.add_parser("set-password", help="set a user's password and log out their browsers")
    u_pw.add_argument("--email", required=True)
    u_pw.add_argument("--clinic", metavar="NAME", help="the account's clinic (needed when the email has several)")
    u_pw.add_argument("--password-stdin", action="store_true", help="read the password from stdin's first line")


def _check_user_exists(email: str, clinic: str | None) -> None:
    with _session(None) as s:
        _user(s, email, clinic)


def _when(value) -> str:
    return "-" if value is None else value.strftime("%Y-%m-%d %H:%M UTC")


def run_account(args: argparse.Namespace) -> int:
    """Carry out a parsed ``tokens list|revoke`` or ``users deactivate|set-password`` command."""
    if args.command == "tokens" and args.action == "list":
        rows = list_tokens(None, clinic=args.clinic)
        if not rows:
            print(_say(args.lang, "cli.tokens_none", clinic=args.clinic))
            return 0
        ident, role, created, revoked, expires, scopes, label, every = \
            _say(args.lang, "cli.tokens_columns").split("|")
        print(f"{ident:>5}  {role:<10} {created:<20} {revoked:<20} {expires:<20} {scopes:<24} {label}")
        for r in rows:
            print(f"{r['id']:>5}  {r['role']:<10} {_when(r['created_at']):<20} {_when(r['revoked_at']):<20} "
                  f"{_when(r['expires_at']):<20} {r['scopes'] or every:<24} {r['label']}")
    elif args.command == "tokens" and args.action == "revoke":
        r = revoke_token(None, args.token_id)
        label = f" ({r['label']})" if r["label"] else ""
        if r["already"]:
            print(_say(args.lang, "cli.token_already_revoked", id=r["id"], clinic=r["clinic"], label=label,
                       when=_when(r["revoked_at"])))
        else:
            print(_say(args.lang, "cli.token_revoked", id=r["id"], clinic=r["clinic"], label=label))
    elif args.command == "users" and args.action == "deactivate":
        closed = deactivate_user(None, email=args.email, clinic=args.clinic)
        print(_say(args.lang, "cli.user_deactivated", email=args.email.strip().lower(), closed=closed))
    elif args.command == "users" and args.action == "set-password":
        if not args.password_stdin:  # an unknown email is said before the prompts, not after
            _check_user_exists(args.email, args.clinic)
        password = _read_password(args.password_stdin, args.lang)
        closed = set_password(None, email=args.email, password=password, clinic=args.clinic)
        print(_say(args.lang, "cli.password_changed", email=args.email.strip().lower(), closed=closed))
    else:  # pragma: no cover - argparse only lets the registered actions through
        raise ValueError(f"unknown action {args.command} {args.action}; see chakamo {args.command} --help")
    return 0


__all__ += ["deactivate_user", "list_tokens", "revoke_token", "run_account", "set_password"]
