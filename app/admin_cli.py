"""Set-up commands of the web application (``chakamo serve``, ``clinics``, ``users``, ``tokens``).

``chakamo serve [--host 127.0.0.1] [--port 8000]``
    The web application on the embedded default (SQLite, local files, in-process jobs) under
    ``CHAKAMO_DATA_DIR``; loopback unless ``--host`` says otherwise.
``chakamo clinics create NAME``
    A new clinic (tenant).
``chakamo users create --clinic NAME --email E --role admin|clinician|read_only [--name N] [--password-stdin]``
    A user; the password is asked twice without echo, or read from the first line of stdin with
    ``--password-stdin`` (for scripts).  There is never a default password.
``chakamo tokens create --clinic NAME [--label L] [--role clinician|read_only|admin]``
    An API token for a hospital system; printed once, alone on the last line of the output (only its
    sha256 is stored, so it cannot be shown again).

The commands use the same settings as the server (``CHAKAMO_DATA_DIR``, ``DATABASE_URL``...), apply the
migrations first, and raise ``ValueError`` with one sentence for anything the user can fix (the CLI prints
it and exits with status 2).  The functions are importable for tests and scripts: their first argument is a
:class:`~app.settings.Settings` (``None``: the environment's).
"""

from __future__ import annotations

import argparse
import getpass
import sys
from typing import TYPE_CHECKING

from app.security import ROLES  # the one definition of the roles (a stdlib-only module: cheap to import)

if TYPE_CHECKING:  # the database stack is imported on use: `chakamo demo` does not pay for it
    from app.db import Database
    from app.settings import Settings

COMMANDS = ("serve", "clinics", "users", "tokens")


def _database(settings: Settings | None) -> Database:
    from app.db import Database
    from app.settings import get_settings

    settings = settings or get_settings()
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    db = Database(settings.db_url)
    db.migrate()
    return db


def _clinic(s, name: str):
    from sqlalchemy import select

    from app.db.models import Clinic

    clinic = s.scalar(select(Clinic).where(Clinic.name == name))
    if clinic is None:
        known = ", ".join(repr(c) for c in s.scalars(select(Clinic.name).order_by(Clinic.name))) or "none yet"
        raise ValueError(f"no clinic named {name!r} (known: {known}); create it with `chakamo clinics create`")
    return clinic


def create_clinic(settings: Settings | None, name: str) -> int:
    """Create clinic ``name``; returns its id.  ValueError if the name is empty or taken."""
    name = name.strip()
    if not name:
        raise ValueError("the clinic name is empty; give a name, e.g. chakamo clinics create \"Clínica Norte\"")
    from sqlalchemy import select

    from app.db.models import Clinic

    db = _database(settings)
    try:
        with db.session() as s:
            if s.scalar(select(Clinic.id).where(Clinic.name == name)) is not None:
                raise ValueError(f"a clinic named {name!r} already exists; choose another name")
            clinic = Clinic(name=name)
            s.add(clinic)
            s.flush()
            return clinic.id
    finally:
        db.dispose()


def create_user(settings: Settings | None, *, clinic: str, email: str, role: str, password: str,
                name: str = "") -> int:
    """Create a user of clinic ``clinic``; returns the id.  ValueError for a bad role, weak password or
    an email already used."""
    if role not in ROLES:
        raise ValueError(f"role {role!r} is unknown; use one of {', '.join(ROLES)}")
    email = email.strip().lower()
    if "@" not in email or len(email) < 3:
        raise ValueError(f"{email!r} is not an email address; give the user's email")
    from sqlalchemy import select

    from app.db.models import User
    from app.security import check_password_strength, hash_password

    check_password_strength(password)
    db = _database(settings)
    try:
        with db.session() as s:
            c = _clinic(s, clinic)
            if s.scalar(select(User.id).where(User.email == email)) is not None:
                raise ValueError(f"the email {email} already has an account; use another email")
            user = User(clinic_id=c.id, email=email, name=name, role=role, password_hash=hash_password(password))
            s.add(user)
            s.flush()
            return user.id
    finally:
        db.dispose()


def create_token(settings: Settings | None, *, clinic: str, label: str = "", role: str = "clinician") -> str:
    """Create an API token of clinic ``clinic`` and return it (the only time it exists in clear)."""
    if role not in ROLES:
        raise ValueError(f"role {role!r} is unknown; use one of {', '.join(ROLES)}")
    from app.db.models import ApiToken
    from app.security import new_token, sha256_hex

    token = new_token()
    db = _database(settings)
    try:
        with db.session() as s:
            c = _clinic(s, clinic)
            s.add(ApiToken(clinic_id=c.id, label=label, role=role, token_sha256=sha256_hex(token)))
        return token
    finally:
        db.dispose()


def serve(host: str = "127.0.0.1", port: int = 8000) -> None:
    """Run the web application with uvicorn until interrupted."""
    import uvicorn

    from app.main import create_app
    from app.settings import get_settings

    settings = get_settings()  # errors (e.g. no secret key) before anything starts
    print(f"ChakaMo on http://{host}:{port}/ (data in {settings.data_dir}); Ctrl-C stops it", file=sys.stderr)
    uvicorn.run(create_app(settings), host=host, port=port, log_level="info")


def add_parsers(sub) -> None:
    """Register ``serve``, ``clinics``, ``users`` and ``tokens`` on the ``chakamo`` subparsers."""
    serve_p = sub.add_parser("serve", help="run the web application (embedded default: SQLite, local files)")
    serve_p.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)")
    serve_p.add_argument("--port", type=int, default=8000, help="port (default: 8000)")

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


def _read_password(from_stdin: bool) -> str:
    if from_stdin:
        return sys.stdin.readline().rstrip("\r\n")
    first = getpass.getpass("Password (at least 10 characters): ")
    if getpass.getpass("Repeat the password: ") != first:
        raise ValueError("the two passwords differ; run the command again")
    return first


def run(args: argparse.Namespace) -> int:
    """Carry out a parsed ``serve`` / ``clinics`` / ``users`` / ``tokens`` command."""
    if args.command == "serve":
        serve(args.host, args.port)
    elif args.command == "clinics":
        clinic_id = create_clinic(None, args.name)
        print(f"clinic {args.name!r} created (id {clinic_id})")
    elif args.command == "users":
        password = _read_password(args.password_stdin)
        user_id = create_user(None, clinic=args.clinic, email=args.email, role=args.role, password=password,
                              name=args.name)
        print(f"user {args.email.strip().lower()} ({args.role}) created in {args.clinic!r} (id {user_id})")
    elif args.command == "tokens":
        token = create_token(None, clinic=args.clinic, label=args.label, role=args.role)
        print(f"API token for {args.clinic!r} ({args.role}{', ' + args.label if args.label else ''}). It is shown "
              "only now: store it in the hospital system; send it as 'Authorization: Bearer <token>'.")
        print(token)
    return 0


__all__ = ["COMMANDS", "add_parsers", "create_clinic", "create_token", "create_user", "run", "serve"]
