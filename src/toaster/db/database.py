"""The database handle: one engine, one long-lived connection, transactions on demand."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from typing import TYPE_CHECKING

from sqlalchemy import Connection, Engine
from sqlalchemy.exc import DBAPIError

from toaster.db import migrate
from toaster.db.dialects import Backend, backend_for
from toaster.db.dialects.base import Cursor
from toaster.db.engine import (
    dbapi,
    default_url,
    describe,
    ensure_wal,
    make_engine,
    normalise_url,
    parse_url,
    read_only_error,
    refused_value,
    sqlite_file,
)
from toaster.errors import DatabaseOpenError

if TYPE_CHECKING:
    from sqlalchemy.engine.interfaces import DBAPIConnection

    from toaster.db.writer.store import RuleFactory, Store
    from toaster.timeutil import TimeFrame


class Database:
    """A toaster database (SQLite file or PostgreSQL), at the code's schema revision.

    Not thread-safe: give each thread its own :func:`toaster.connect`. Use it as a context
    manager or call :meth:`close`.

    ``rules`` make the rules its :meth:`store` runs on every fact write, each called once with
    that store; the database layer knows none of them (:func:`toaster.connect`, the
    composition root in :mod:`toaster.app.session`, hands it the belief rule).
    """

    def __init__(self, engine: Engine, url: str, *, rules: Sequence[RuleFactory] = ()) -> None:
        self.engine = engine
        self.url = url
        self.backend: Backend = backend_for(engine.dialect.name)
        self.rules: tuple[RuleFactory, ...] = tuple(rules)
        self._conn: Connection | None = None
        self._store: Store | None = None
        #: the page cache bound of this handle's connections, KiB (None: the engine's)
        self.page_cache_kib: int | None = None

    @property
    def dialect_name(self) -> str:
        """``sqlite`` or ``postgresql``."""
        return self.engine.dialect.name

    @property
    def connection(self) -> Connection:
        """The long-lived connection shared by the store and the queries."""
        if self._conn is None or self._conn.closed:
            self._conn = self.engine.connect()
            if self.page_cache_kib is not None:
                self.raw_connection(self._conn)
        return self._conn

    def raw_connection(self, conn: Connection) -> DBAPIConnection:
        """The DBAPI connection under ``conn``, with this handle's page cache bound."""
        raw = dbapi(conn)
        if self.page_cache_kib is not None:
            self.backend.set_page_cache(raw, self.page_cache_kib)
        return raw

    def set_page_cache(self, kib: int) -> None:
        """Bound the page cache of this handle's connections to ``kib`` KiB (SQLite; the
        server holds PostgreSQL's). The engine's default, 64 MiB, speeds up crowds of
        hundreds; a long-running node with a small scene fills it for hours for no gain."""
        if kib <= 0:
            msg = f"page cache of {kib} KiB must be positive"
            raise ValueError(msg)
        self.page_cache_kib = int(kib)
        if self._conn is not None and not self._conn.closed:
            self.raw_connection(self._conn)

    @contextmanager
    def transaction(self, *, write: bool = False) -> Iterator[Connection]:
        """One transaction (nested calls join the open one). ``write`` takes SQLite's write
        lock up front so that two writers never deadlock half-way. A value the database
        refuses (:func:`~toaster.db.engine.refused_value`) leaves the outermost transaction,
        rolled back, as one :class:`~toaster.errors.InvalidInputError`; a write refused by a
        read-only server (a hot standby) as one :class:`~toaster.errors.ReadOnlyError`."""
        conn = self.connection
        if conn.in_transaction():
            yield conn
            return
        conn.info["write"] = write
        try:
            with conn.begin():
                yield conn
        except Exception as exc:  # raw cursors raise the drivers' own errors
            error = refused_value(exc) or read_only_error(
                exc, describe(self.engine.url), None if conn.invalidated else dbapi(conn)
            )
            if error is None:
                raise
            raise error from exc

    def reset_connection(self) -> None:
        """Drop the long-lived connection and the pool's others, unused and without a word
        from the server (after a lost connection or a server restart: they are dead, or
        may be); the next use connects again. Outside a transaction."""
        conn, self._conn = self._conn, None
        if conn is not None:
            with suppress(Exception):  # a dead connection may fail to say goodbye
                conn.invalidate()  # its driver connection is closed, not returned to the pool
                conn.close()
        self.engine.dispose()

    def cursor(self) -> Cursor:
        """A raw DBAPI cursor on the shared connection (inside a transaction)."""
        return dbapi(self.connection).cursor()

    def maintain(self) -> None:
        """Reclaim what long runs leave behind, outside any transaction: PostgreSQL vacuums
        and analyzes the hot tables (dead row versions of closed and refreshed intervals, for
        servers whose autovacuum is off or late); SQLite folds its WAL into the file."""
        if self.connection.in_transaction():
            msg = "maintain() runs outside a transaction: call it between ticks"
            raise RuntimeError(msg)
        raw = dbapi(self.connection)
        self.backend.maintain(raw)

    def vacuum_scratch(self) -> bool:
        """Vacuum this session's scratch tables of the belief rule (PostgreSQL; see
        :mod:`toaster.rules.hook`), outside any transaction; False, doing nothing, inside
        one."""
        if self.connection.in_transaction():
            return False
        self.backend.vacuum_scratch(dbapi(self.connection))
        return True

    def store(self) -> Store:
        """The write API (one per database handle, it remembers what each source wrote), with
        this handle's rules installed (the belief rule, for :func:`toaster.connect`)."""
        if self._store is None:
            from toaster.db.writer.store import Store

            store = Store(self)
            # Every store applies the rules, so that several writer processes all keep the
            # other agents' beliefs up to date.
            for make_rule in self.rules:
                store.add_rule(make_rule(store))
            self._store = store
        return self._store

    def time_frame(self, style: str = "auto") -> TimeFrame:
        """The frame of this database's data (:class:`toaster.timeutil.TimeFrame`): its
        recorded start; without one, its first event (the epoch when that is simulated time,
        before 1971), so that durations typed before and after a write agree."""
        from sqlalchemy import func, select

        from toaster.db import schema
        from toaster.db.catalog import data_start_ns
        from toaster.timeutil import TimeFrame, start_from_first

        with self.transaction() as conn:
            start = data_start_ns(conn)
            if start is None:
                first = conn.execute(select(func.min(schema.events.c.stamp_ns))).scalar()
                start = None if first is None else start_from_first(int(first))
        return TimeFrame(start, style)

    def close(self) -> None:
        """Close the connection and dispose of the engine."""
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        self.engine.dispose()

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_database(
    url: str | None = None,
    *,
    create: bool = True,
    check: bool = True,
    rules: Sequence[RuleFactory] = (),
    allow_memory: bool = False,
) -> Database:
    """Open a toaster database whose store runs ``rules`` (none by default: applications use
    :func:`toaster.connect`, which gives it the belief rule).

    Args:
        url: ``sqlite:///file.db``, ``postgresql://host/db`` or a path ending in ``.db``;
            default ``$TOASTER_DB`` or ``sqlite:///toaster.db``.
        create: create a missing SQLite file, and migrate a database that has no table yet
            (a new file or database) to head, atomically (see :func:`open_engine`).
        check: raise :class:`~toaster.errors.SchemaOutdatedError` when an existing database is
            not at the code's revision (the message says to run ``toaster db upgrade``).
        rules: what :meth:`Database.store` installs (see :class:`Database`).
        allow_memory: accept in-memory SQLite (``sqlite://``), which keeps nothing once
            closed: for throw-away databases of one thread.

    Every error a user can cause (bad URL, unreachable server, a file that is not a toaster
    database, a lock held too long) is a :class:`~toaster.errors.ToasterError`.
    """
    engine, revision = open_engine(url, create=create, allow_memory=allow_memory)
    try:
        if check and not (create and revision is None):  # else just made at head
            migrate.check_at_head(engine, url_hint=url or "")
    except BaseException:
        engine.dispose()
        raise
    return Database(engine, normalise_url(url or default_url()), rules=rules)


def open_engine(
    url: str | None = None,
    *,
    create: bool = False,
    revision: str = "head",
    allow_memory: bool = False,
) -> tuple[Engine, str | None]:
    """An engine on a toaster database, and the revision it was found at (None: a new or
    empty database, migrated to ``revision`` when ``create``).

    ``create``: a missing (or empty) SQLite file is built aside and moved into place at
    ``revision`` (a crash leaves no half-made file); an empty database is migrated to
    ``revision`` in one transaction (concurrent openers wait and migrate once). Without it a
    missing SQLite file is an error and nothing is created. Another application's database
    is refused, unchanged.
    """
    parsed = parse_url(url, allow_memory=allow_memory)
    where = describe(parsed)
    path = sqlite_file(parsed)
    created = False
    if path is not None and migrate.is_new_file(path):
        if not create:
            shown = url or default_url()
            msg = (
                f"no SQLite database at {where!r}: check the path, or create it with "
                f"`toaster --db {shown} db upgrade`"
            )
            raise DatabaseOpenError(msg)
        created = migrate.create_sqlite_file(path, revision)
    engine = make_engine(url, allow_memory=allow_memory)
    try:
        with engine.connect() as conn:
            # A file just made is a copy of the template or migrated: at ``revision``, in WAL.
            current = revision if created else migrate.toaster_revision(conn, where)
        if current is None and create:
            migrate.upgrade(engine, revision)
        elif current is not None:
            ensure_wal(engine)
    except DBAPIError as exc:  # one the engine's handle_error left as it was
        engine.dispose()
        reason = (str(exc.orig).strip().splitlines() or [type(exc.orig).__name__])[0]
        msg = f"cannot open database {where!r}: {reason}"
        raise DatabaseOpenError(msg) from None
    except BaseException:
        engine.dispose()
        raise
    return engine, None if created else current
