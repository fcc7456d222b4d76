"""Database access: engine and session factory for one URL, and the Alembic upgrade applied at start-up.

``Database(url)`` owns one engine; SQLite gets WAL journaling (readers never wait for the job threads'
writes), ``synchronous=FULL`` (a commit — an acknowledged upload — survives a power cut; NORMAL could
roll the last commits back), foreign keys on and a busy timeout, on every connection.

**SQLite's one write lock, queued** (issue 16 finding 10h).  A SQLite database has one write lock; a writer that
finds it taken sleeps in SQLite's busy handler (1, 2, 5, 10 … then 100 ms at a time) and tries again.  Under an
upload burst that handler decided who wrote next: a writer that had waited long looked again only every 100 ms while
newcomers slipped in first, and every waiter held a pooled connection meanwhile (``py-spy dump`` of ``chakamo
serve`` as ``benchmarks.load``'s burst began: 34 request threads inside SQLite's ``execute``, 25 of them reads
whose audit row their commit was writing).  So the server's writers of one database file queue in the process at
a :class:`WriteGate` (one per file, :func:`write_gate`, shared by every engine on it): the moment a writer commits
or rolls back, the writer that has waited longest is woken — no polling.  Not a strict hand-over: the gate is free
from the release on, and a writer that is running just then may take it first — except that while a group-commit
batch waits (:meth:`WriteGate.acquire` with ``first``), the gate is kept for it: the others wait, and one that was
woken and lost the race waits again behind later arrivals (bounded by :data:`WRITE_WAIT_S`).  A hand-over to a thread the
operating system has not scheduled yet keeps the lock idle until it runs (a lock convoy); on a machine starved of
CPU that can cost more than the order saves (the first version of this gate handed over; two login-flood runs with
it at load 25–29 were worse than main's, noisy as such runs are).  The gate is taken where pysqlite
opens a write transaction (just before the first INSERT/UPDATE/DELETE/REPLACE outside one: reads take nothing,
and a read-only request never waits for it) and given back by ``commit()``, ``rollback()`` or ``close()`` of that
connection (:class:`GatedConnection`, the engine's connection class).  A writer waits at most
:data:`WRITE_WAIT_S` (SQLite's own busy timeout), then gets SQLite's "database is locked".  Other processes on the
same file (the ``chakamo`` commands) still meet this one in SQLite's busy handler, as before.
:func:`ensure_blobs` records stored files with the dialect's ``INSERT … ON CONFLICT DO NOTHING``
(SQLite, PostgreSQL): two transactions storing equal content at the same time never collide.
``Database.migrate()`` upgrades the schema to the newest revision of ``app/store/migrations`` programmatically
(no ``alembic.ini`` needed).
Nothing is created at import time.
"""

from __future__ import annotations

import re
import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from sqlalchemy import create_engine, event, make_url
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

from app.store.group_commit import GroupCommit
from app.store.models import Base, Blob

MIGRATIONS_DIR = Path(__file__).resolve().parent / "migrations"


class WriteGate:
    """A queue for one SQLite database's single write lock, in this process (module docstring).  :meth:`release`
    wakes the writer that has waited longest at once (no polling); a writer arriving at that moment may still go
    first (no strict hand-over: see the module docstring).

    Writers taking it with ``first=True`` (the group commit's batches, :func:`writes_first`) go ahead of the others:
    a release wakes the longest waiting of them if any, and no other writer takes the gate while one of them waits.
    One such batch holds the audit rows of every read waiting to answer, which would otherwise queue behind each
    upload and patient creation of a burst (issue 16 finding 10h).  The others are not starved: the group commit
    has one batch writing at a time, and each batch takes every row that arrived before it; but one of them woken
    as a batch arrived waits again behind later arrivals (``Condition.wait_for`` queues it anew), within
    :data:`WRITE_WAIT_S`.

    The lock is re-entrant: an unclosed connection holding the gate gives it back from its finaliser
    (:meth:`GatedConnection.__del__`, SQLAlchemy's pool finaliser's rollback), which a garbage-collection pass may
    run in any thread at any allocation — also in a thread that is inside :meth:`acquire` or :meth:`release` here,
    holding this lock (with a plain lock that thread deadlocked on itself, and every writer after it).  Nothing
    between a waiter's look at the gate and its sleep allocates a collected object (the predicates are made once),
    so a nested release cannot slip in there; were one missed, the waiter would still find the gate free when its
    timeout ends (``wait_for`` looks once more) — late, not failed."""

    def __init__(self) -> None:
        lock = threading.RLock()
        self._cond = threading.Condition(lock)  # the writers in arrival order
        self._first = threading.Condition(lock)  # the writers going first
        self._held = False
        self._waiting = 0
        self._waiting_first = 0
        self._free = lambda: not self._held  # made once: nothing to allocate while waiting
        self._free_for_others = lambda: not self._held and not self._waiting_first

    def acquire(self, timeout_s: float, first: bool = False) -> bool:
        """Take the gate, waiting at most ``timeout_s`` (ahead of the other writers when ``first``); False on
        timeout."""
        with self._cond:
            if self._free() if first else self._free_for_others():
                self._held = True
                return True
            taken = False
            if first:
                self._waiting_first += 1
                try:
                    taken = self._first.wait_for(self._free, timeout_s)
                finally:
                    self._waiting_first -= 1
                    if not taken and not self._held:  # interrupted after a release woke it: pass the wake-up on
                        (self._first if self._waiting_first else self._cond).notify()
            else:
                self._waiting += 1
                try:
                    taken = self._cond.wait_for(self._free_for_others, timeout_s)
                finally:
                    self._waiting -= 1
            if taken:
                self._held = True
            return taken

    def release(self) -> None:
        with self._cond:
            self._held = False
            # the longest waiter (a Condition wakes its waiters in the order they came), a first-going one before
            (self._first if self._waiting_first else self._cond).notify()

    @property
    def waiting(self) -> int:
        """Writers waiting for the gate right now (those going first included)."""
        return self._waiting + self._waiting_first


#: one gate per SQLite database file in this process (every engine on that file shares it)
_GATES: dict[str, WriteGate] = {}
_GATES_LOCK = threading.Lock()
#: this thread's write transactions take the gate ahead of the other writers (:func:`writes_first`)
_GOING_FIRST = threading.local()


@contextmanager
def writes_first() -> Iterator[None]:
    """Inside it, the write transactions this thread opens on a SQLite file take its :class:`WriteGate` ahead of the
    writers waiting there (the group commit's batches: :class:`app.store.group_commit.GroupCommit`); elsewhere a
    no-op."""
    before = getattr(_GOING_FIRST, "on", False)
    _GOING_FIRST.on = True
    try:
        yield
    finally:
        _GOING_FIRST.on = before


#: longest wait for the write gate, as SQLite's own busy timeout (then "database is locked", as SQLite says)
WRITE_WAIT_S = 15.0
#: the statements before which pysqlite opens a write transaction (it begins none for reads)
_DML = ("INSERT", "UPDATE", "DELETE", "REPLACE")
#: what pysqlite skips before it looks at a statement's first word: whitespace, ``-- …`` and ``/* … */`` comments
_LEADING = re.compile(r"(?:\s+|--[^\n]*(?:\n|$)|/\*.*?(?:\*/|$))*", re.DOTALL)


def _is_dml(sql: str) -> bool:
    """Whether pysqlite opens a write transaction before ``sql`` (its first word after whitespace and comments)."""
    return sql[_LEADING.match(sql).end():][:7].upper().startswith(_DML)


def write_gate(path: str) -> WriteGate:
    """The :class:`WriteGate` of the SQLite database file ``path`` (created at the first call)."""
    key = str(Path(path).resolve())
    with _GATES_LOCK:
        return _GATES.setdefault(key, WriteGate())


class _GatedCursor(sqlite3.Cursor):
    """A cursor that takes the gate before a write; a statement that fails before its transaction began (it
    could not be prepared) gives the gate back at once."""

    def execute(self, sql, parameters=(), /):
        return self._gated(super().execute, sql, parameters)

    def executemany(self, sql, seq_of_parameters, /):
        return self._gated(super().executemany, sql, seq_of_parameters)

    def _gated(self, call, sql, parameters):
        """``call(sql, parameters)`` after taking the gate if ``sql`` opens a write transaction."""
        self.connection.enter_write(sql)
        try:
            return call(sql, parameters)
        except BaseException:
            self.connection._leave()
            raise


class GatedConnection(sqlite3.Connection):
    """A pysqlite connection whose write transactions queue at the database's :class:`WriteGate`: pysqlite opens a
    transaction just before the first INSERT/UPDATE/DELETE/REPLACE outside one, and that is where the gate is
    taken; ``commit()`` / ``rollback()`` / ``close()`` give it back once SQLite's lock is free (module docstring).

    Only these cursors' ``execute`` / ``executemany`` (:meth:`cursor`, what SQLAlchemy uses) take the gate.  Three
    ways past it: pysqlite's shortcuts ``Connection.execute`` / ``executemany`` / ``executescript`` make a plain
    cursor in C, past :meth:`cursor`; and a gated cursor's own ``executescript`` is not wrapped (a script may
    open and close its own transactions).  Nothing in the app uses any of them on a gated connection."""

    def __init__(self, database, *args, **kwargs) -> None:
        super().__init__(database, *args, **kwargs)
        self._gate = None if str(database) in ("", ":memory:") or str(database).startswith("file:") \
            else write_gate(str(database))
        self._holds = False

    def cursor(self, factory=_GatedCursor):
        return super().cursor(factory)

    def enter_write(self, sql: str) -> None:
        if self._gate is None or self._holds or self.in_transaction:
            return
        if _is_dml(sql):
            if not self._gate.acquire(WRITE_WAIT_S, first=getattr(_GOING_FIRST, "on", False)):
                raise sqlite3.OperationalError("database is locked")
            self._holds = True

    def _leave(self) -> None:
        if self._holds and not self.in_transaction:
            self._holds = False
            self._gate.release()

    def commit(self) -> None:
        try:
            super().commit()
        finally:
            self._leave()

    def rollback(self) -> None:
        try:
            super().rollback()
        finally:
            self._leave()

    def close(self) -> None:
        try:
            super().close()
        finally:
            self._drop()

    def __del__(self) -> None:  # collected unclosed: SQLite frees its lock with the connection, the gate goes too
        self._drop()

    def _drop(self) -> None:
        if getattr(self, "_holds", False):
            self._holds = False
            self._gate.release()


def _sqlite_pragmas(dbapi_connection, connection_record) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA synchronous=FULL")
    cursor.close()


#: connections a server process keeps (and may add) per database, and how long a request waits for one:
#: as many as FastAPI's request threads (40), so requests never queue for a connection behind each other —
#: on SQLite too (SQLAlchemy's default there is 5 + 10, waited for 30 s): a SQLite writer waits up to the busy
#: timeout for the one write lock *holding its connection*, so during an upload burst (each upload places its
#: files under that lock) 15 waiting writers used to leave no connection for any other request — a plain read,
#: which in WAL mode never waits for a writer, waited 30 s for a connection, and the pile-up fed itself
#: (issue 16 finding 10h).  A request's own session holds its connection across thread hops, so the server lets
#: fewer requests hold one at once than there are connections (``REQUEST_SESSIONS`` in app/web/api/deps.py)
POOL_SIZE, POOL_OVERFLOW, POOL_TIMEOUT_S = 20, 20, 10.0


def make_engine(url: str) -> Engine:
    """An engine for ``url`` with a pool of :data:`POOL_SIZE` (+ :data:`POOL_OVERFLOW`) connections waited for at
    most :data:`POOL_TIMEOUT_S`; for a SQLite file its folder is created and the pragmas above applied; a server
    database's connections are checked before use (a restarted server's dead connections are replaced)."""
    if url.startswith("sqlite"):
        path = make_url(url).database
        pool = {}  # an in-memory database keeps a pool of its own kind
        if path and path != ":memory:":
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            pool = dict(pool_size=POOL_SIZE, max_overflow=POOL_OVERFLOW, pool_timeout=POOL_TIMEOUT_S)
        engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": WRITE_WAIT_S, "factory": GatedConnection}, **pool)
        event.listen(engine, "connect", _sqlite_pragmas)
    else:
        engine = create_engine(url, pool_pre_ping=True, pool_size=POOL_SIZE, max_overflow=POOL_OVERFLOW,
                               pool_timeout=POOL_TIMEOUT_S)
    event.listen(engine, "before_cursor_execute", _note_write)
    return engine


_WROTE = "chakamo_wrote"  # Connection.info: a write statement ran in the connection's current transaction
_CONNECTIONS = "chakamo_connections"  # Session.info: the connections of its current transaction


def _note_write(conn, cursor, statement, parameters, context, executemany) -> None:
    if _is_dml(statement):
        conn.info[_WROTE] = True


def _track_connection(session: Session, transaction, connection) -> None:
    """``after_begin``: a session's transaction took ``connection``, which has written nothing in it yet (a
    savepoint's begin is no new transaction: what the connection wrote before it stands)."""
    if transaction.nested:
        return
    connection.info[_WROTE] = False
    session.info.setdefault(_CONNECTIONS, []).append(connection)


def alembic_config(engine: Engine):
    """An Alembic ``Config`` pointing at ``app/store/migrations`` and at ``engine`` (used by :meth:`Database.migrate`)."""
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.set_main_option("sqlalchemy.url", engine.url.render_as_string(hide_password=False).replace("%", "%%"))
    return cfg


#: rows of one multi-row INSERT (3 parameters each: within the 999 of older SQLite builds)
_ROWS_PER_INSERT = 300


def ensure_blobs(db: Session, blobs: list[tuple[str, int]]) -> None:
    """Add the :class:`Blob` row of each ``(sha256, size_bytes)`` of ``blobs`` unless it exists — atomic, safe against
    concurrent inserts; one statement per :data:`_ROWS_PER_INSERT` rows on SQLite and PostgreSQL (an upload reserves
    its files' rows while it holds the database's write lock: not one statement per file)."""
    if not blobs:
        return
    name = db.get_bind().dialect.name
    if name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    elif name == "sqlite":
        from sqlalchemy.dialects.sqlite import insert
    else:  # another database: check, then insert (no concurrent guarantee)
        for sha256, size_bytes in blobs:
            if db.get(Blob, sha256) is None:
                db.add(Blob(sha256=sha256, size_bytes=size_bytes))
                db.flush()
        return
    from app.store.models import utcnow

    now = utcnow()
    rows = [{"sha256": sha, "size_bytes": size, "created_at": now} for sha, size in dict(blobs).items()]
    for i in range(0, len(rows), _ROWS_PER_INSERT):
        db.execute(insert(Blob).values(rows[i:i + _ROWS_PER_INSERT]).on_conflict_do_nothing(index_elements=["sha256"]))


_AT_COMMIT = "chakamo_add_at_commit"  # the Session.info key of the rows add_at_commit queued
_at_commit_hooked = False
_at_commit_lock = threading.Lock()


def _add_queued(session: Session) -> None:
    session.add_all(session.info.pop(_AT_COMMIT, ()))  # before_commit: the commit's own flush writes them


def _drop_queued(session: Session, transaction) -> None:
    if transaction.parent is None:  # the outermost transaction ended without them (rolled back, closed): they go
        session.info.pop(_AT_COMMIT, None)  # with it, as rows flushed in it would (a savepoint's end keeps them)
        session.info.pop(_CONNECTIONS, None)


def _only_queued(db: Session) -> list:
    """The rows :func:`add_at_commit` queued, taken out of ``db``, when they are all its transaction would write
    (nothing flushed or executed that writes, nothing pending); else ``[]`` and ``db`` keeps them.

    Seen as writes: every statement SQLAlchemy executes whose first word is INSERT/UPDATE/DELETE/REPLACE
    (:func:`_note_write`: flushes, ``update()``/``delete()``, ``text()``, ``connection().execute``).  Not seen — so
    never to be used beside an ``add_at_commit`` row: a raw driver cursor, ``executescript``, and a write that
    starts with ``WITH`` (which pysqlite's own transaction start, and so the write gate, does not see either)."""
    if not db.info.get(_AT_COMMIT) or db.new or db.dirty or db.deleted:
        return []
    if any(c.info.get(_WROTE) for c in db.info.get(_CONNECTIONS, ())):
        return []
    return db.info.pop(_AT_COMMIT)


def _hook_sessions() -> None:
    """Register the :class:`~sqlalchemy.orm.Session` events of :func:`add_at_commit` and of the group commit's
    choice (:func:`_only_queued`) once, before a session of a :class:`Database` begins (never at import)."""
    global _at_commit_hooked
    with _at_commit_lock:
        if not _at_commit_hooked:
            event.listen(Session, "before_commit", _add_queued)
            event.listen(Session, "after_transaction_end", _drop_queued)
            event.listen(Session, "after_begin", _track_connection)
            _at_commit_hooked = True


def add_at_commit(db: Session, row) -> None:
    """Add ``row`` to ``db`` when ``db`` commits, not before: written by the commit's flush, in the thread that
    commits; gone if the transaction is rolled back instead (exactly what a row flushed now would do).

    Why: on SQLite a row written now takes the one write lock until the commit.  A request whose route runs on one
    thread-pool thread and whose commit runs on another (FastAPI: a ``def`` route, then its response's validation
    on the pool, then the session dependency's exit) would hold that lock while it queues for a pool thread — and
    when every pool thread is a request waiting for that same lock (a login flood, an upload burst), nobody moves
    until SQLite's busy timeout (15 s) gives up on the waiters: reads timed out at 30 s (issue 16 finding 2).
    A row added at commit takes the lock only inside the commit, which holds no pool thread while it waits (the
    dependency's exit runs without the pool's limit).  Not touched by autoflush: the row is outside the session
    until then.  The hooks are registered on :class:`~sqlalchemy.orm.Session` by the first :class:`Database` or call
    (never at import).  In :meth:`Database.session`, rows that are all the transaction writes go to the group
    commit, which writes a row's column values only (standalone rows such as audit events, not related rows)."""
    _hook_sessions()
    if not db.in_transaction():
        db.begin()  # the row belongs to a transaction: its end without a commit drops it
    db.info.setdefault(_AT_COMMIT, []).append(row)


class Database:
    """One database: ``engine``, ``sessions()`` (a sessionmaker) and :meth:`session` as a context manager."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.engine = make_engine(url)
        self.sessions = sessionmaker(self.engine, expire_on_commit=False)
        self.group = GroupCommit(self.sessions, first=writes_first)
        _hook_sessions()

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A session committed on success, rolled back on error, always closed.

        When the rows :func:`add_at_commit` queued are all its transaction writes (a read's audit event), they are
        written by the database's group commit (:mod:`app.store.group_commit`) after the session has closed (its
        connection back in the pool meanwhile), together with other sessions' such rows; the exit returns once they
        are committed, and raises :class:`~app.store.group_commit.GroupWriteFailed` if they were refused."""
        with self.sessions() as db:
            try:
                yield db
                grouped = _only_queued(db)
                db.commit()
            except BaseException:
                db.rollback()
                raise
        if grouped:
            self.group.write(grouped)

    def migrate(self, sealing_key: bytes | None = None) -> None:
        """Upgrade the schema to the newest revision (idempotent).  ``sealing_key``: ``CHAKAMO_SECRET_KEY``'s bytes
        (``Settings.sealing_key``), which migration 0012 seals stored plain secrets under; without it that migration
        stops when it finds one."""
        from alembic import command

        cfg = alembic_config(self.engine)
        with self.engine.begin() as connection:
            cfg.attributes["connection"] = connection
            cfg.attributes["sealing_key"] = sealing_key
            command.upgrade(cfg, "head")

    def dispose(self) -> None:
        self.engine.dispose()


__all__ = ["Base", "Database", "MIGRATIONS_DIR", "add_at_commit", "alembic_config", "ensure_blobs", "make_engine",
           "writes_first"]
