"""Group commit: rows that are all a transaction writes (a read's audit event) are written together with every such
row that arrives meanwhile — one transaction, one write lock, one flush to disk for the lot.

Why (issue 16, the 20-clinician upload burst on the embedded default): every audited read was a write transaction
of its own, and on SQLite all writers of the file queue for one write lock (:class:`app.store.database.WriteGate`),
each holding it across its commit's ``fsync`` (``synchronous=FULL``).  At 50 reads/s beside the uploads and the
jobs' progress, ``py-spy dump`` of the server found a dozen request threads waiting at that gate on average, for
their one-row commits; reads that write no row (``GET /jobs/{id}``) answered twice as fast as audited ones.  A
database's group commit is the known cure: a commit that has to wait anyway takes the others' rows with it.

How — leader and followers, no thread of its own.  :meth:`GroupCommit.write` queues the caller's rows.  A caller
that finds no batch being written leads: it takes the queued rows (at most :data:`MAX_BATCH_ROWS`; its own always
among them), writes them in one transaction of a session of its own, and wakes the callers whose rows those were.
If rows arrived meanwhile it hands the lead to the first of their callers, who writes the next batch (the leader's
own request has waited its turn and goes on).  While one batch is written, the next one gathers: the busier the
server, the larger the batches, and one writer at a time takes the lock for all of them.

Fail closed, per caller: a caller returns only once its rows are committed; if the database refuses a row of a batch,
each of its callers' rows is written again alone, and only a caller whose own rows the database refuses gets the error
(:class:`GroupWriteFailed`; a read then answers 500 without its data, as when its own commit failed).  A database that
cannot write at all fails the batch at once.  One batch at a time: while a leader waits for the write lock (at most
the gate's wait, :data:`app.store.database.WRITE_WAIT_S`), the audited reads of the process wait behind it — as
they waited at the lock before, one by one.  So a batch goes ahead of the other writers waiting for that lock
(``first``): in a burst's first seconds, ``py-spy dump`` found 11–26 reads waiting in the group commit while its
leader queued behind 14 patient and session creations and uploads, each a transaction with its own ``fsync``.  The hand-over of the lead is strict (the next batch waits until its
leader's thread runs), the kind of hand-over :class:`app.store.database.WriteGate` avoids for single writers (a
convoy on a starved CPU); here one hand-over moves a whole batch, and the closed-loop reads measured more per second
with it (16 clients reading one patient on the idle server: 97–111 against 93 reads/s, API CPU per read 7.9–10.0
against 9.1–11.5 ms; issue 16, stop 25), but the burst under load was not conclusive.

Rows: standalone rows with plain column values (the audit events): relationships of a row are not written.  The rows get
their ids and column defaults when written (an ``at_commit`` row has no id before, as documented there).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import inspect, insert
from sqlalchemy.exc import DataError, IntegrityError
from sqlalchemy.orm import sessionmaker

#: most rows written in one batch (a bound on one transaction's size, far above a burst's batches)
MAX_BATCH_ROWS = 500


class GroupWriteFailed(RuntimeError):
    """This caller's rows were not written (its cause is the database's error: a refused row, a lock or pool
    timeout, a lost server)."""


@dataclass(eq=False)
class _Caller:
    rows: list[tuple[type, dict[str, Any]]]
    woken: threading.Event = field(default_factory=threading.Event)
    lead: bool = False  # woken to write the next batch
    error: BaseException | None = None


def _raise(caller: _Caller) -> None:
    """Raise the error of ``caller``'s rows, if any: the database's as :class:`GroupWriteFailed`, an interruption
    (not an ``Exception``) as it is."""
    if caller.error is None:
        return
    if not isinstance(caller.error, Exception):
        raise caller.error
    raise GroupWriteFailed(f"the database did not write {len(caller.rows)} row(s)") from caller.error


def values_of(row) -> tuple[type, dict[str, Any]]:
    """``(mapped class, column values)`` of a new ORM ``row``: the values set on it, without the primary key and
    without unset (None) columns that have a default (the insert fills those in)."""
    mapper = inspect(row).mapper
    out: dict[str, Any] = {}
    for attr in mapper.column_attrs:
        value = getattr(row, attr.key)
        column = attr.columns[0]
        if value is None and (column.primary_key or column.default is not None or column.server_default is not None):
            continue
        out[attr.key] = value
    return mapper.class_, out


class GroupCommit:
    """The group commit of one database (module docstring), writing with sessions of ``sessions``, each batch inside
    ``first()`` (the database's :func:`app.store.database.writes_first`: ahead of the other writers at the lock)."""

    def __init__(self, sessions: sessionmaker, max_batch_rows: int = MAX_BATCH_ROWS,
                 first: Callable[[], AbstractContextManager] = nullcontext) -> None:
        self._sessions = sessions
        self._first = first
        self._max = max_batch_rows
        self._lock = threading.Lock()
        self._queue: list[_Caller] = []
        self._writing = False  # a leader is writing (then a caller that arrives waits)

    def write(self, rows: Sequence) -> None:
        """Write the new ORM ``rows`` (their column values as they are now), together with other callers' rows;
        return once they are committed.  Raises :class:`GroupWriteFailed` when the database refused them."""
        me = _Caller([values_of(r) for r in rows])
        with self._lock:
            self._queue.append(me)
            lead = not self._writing
            self._writing = True
        if not lead:
            try:
                me.woken.wait()
            except BaseException:  # interrupted while queued: leave the queue, pass on a lead handed over
                self._abandon(me)
                raise
            if not me.lead:
                _raise(me)
                return
        self._lead(me)

    def _abandon(self, me: _Caller) -> None:
        with self._lock:
            if me in self._queue:  # not taken into a batch yet (a batch's callers are woken by their leader)
                self._queue.remove(me)
            following = self._pass_lead() if me.lead else None
        if following is not None:
            following.woken.set()

    def _pass_lead(self) -> _Caller | None:
        """With the lock held: the queue's head, made the next leader (to be woken), or None and no one writes."""
        following = self._queue[0] if self._queue else None
        if following is None:
            self._writing = False
        else:
            following.lead = True
        return following

    def _lead(self, me: _Caller) -> None:
        with self._lock:  # the queue's head is this caller (a new leader finds an empty queue, a handed lead is first)
            n, rows = 0, 0
            while n < len(self._queue) and (n == 0 or rows + len(self._queue[n].rows) <= self._max):
                rows += len(self._queue[n].rows)
                n += 1
            batch, self._queue = self._queue[:n], self._queue[n:]
        try:
            self._commit(batch)
        finally:
            with self._lock:
                following = self._pass_lead()
            for caller in batch:
                if caller is not me:
                    caller.woken.set()
            if following is not None:
                following.woken.set()
        _raise(me)

    def _commit(self, batch: list[_Caller]) -> None:
        """Write every caller's rows in one transaction; if the database refused a row (``IntegrityError``,
        ``DataError``: that row's fault), each caller's alone (``error`` set on those it refuses).  Any other
        failure — locked past the write wait, a full disk, no pooled connection, the server away — fails the
        whole batch at once: writing each alone would only wait as long again per caller.  Never raises (the
        callers must all be woken); an interruption (``BaseException``) stops the writing and reaches every caller."""
        try:
            self._insert([row for caller in batch for row in caller.rows])
            return
        except BaseException as exc:  # noqa: BLE001 — given to the callers
            if len(batch) == 1 or not isinstance(exc, (IntegrityError, DataError)):
                for caller in batch:
                    caller.error = exc
                return
        for i, caller in enumerate(batch):
            try:
                self._insert(caller.rows)
            except (IntegrityError, DataError) as exc:
                caller.error = exc
            except BaseException as exc:  # noqa: BLE001 — the rest cannot be written either
                for rest in batch[i:]:
                    rest.error = exc
                return

    def _insert(self, rows: list[tuple[type, dict[str, Any]]]) -> None:
        by_class: dict[type, list[dict[str, Any]]] = {}
        for cls, values in rows:
            by_class.setdefault(cls, []).append(values)
        with self._first(), self._sessions.begin() as db:  # committed at the end, rolled back on any error
            for cls, values in by_class.items():
                db.execute(insert(cls), values)


__all__ = ["GroupCommit", "GroupWriteFailed", "MAX_BATCH_ROWS", "values_of"]
