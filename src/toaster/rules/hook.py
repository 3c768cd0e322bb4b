"""The belief rule, as the library starts it: the database runs it (triggers on
``belief_runs``, declared once in :mod:`toaster.rules.pipeline`) in the transaction of every
self write, whoever the writer is.

Per write (a *tick*) the store puts the changed self keys into ``belief_changed`` and inserts
one ``belief_runs`` row; the database's trigger then runs a fixed number of set-based
statements whatever the number of agents: one recursive query computes who perceives what
(rooms, containers, visibility, nested holders), and one ``INSERT ... SELECT`` / ``UPDATE`` per
kind of row writes what changes. Plain SQL clients get the same through ``fact_inbox``.

A holder whose belief equals the self's and who perceives its changes *follows* the self key
(``belief_follow``): the views show it the self's intervals and events, so such a change
writes no holder row. Rows are written only when a holder starts following (its own event,
its own interval closed), stops (it missed a change: its own interval continues the value it
held, a false belief), or when its perception confidence changes.
"""

from __future__ import annotations

import functools
import re
import weakref
from typing import TYPE_CHECKING, Any

from sqlalchemy import Connection, text

from toaster.model import HOLDER_SEPARATOR
from toaster.rules import sqltext
from toaster.rules.pipeline import statements as split
from toaster.rules.sqltext import UNGROUP
from toaster.timeutil import now_ns

if TYPE_CHECKING:
    from toaster.db.writer.changes import ChangeSet
    from toaster.db.writer.store import Store

SOURCE = "beliefs"
SEPARATOR = HOLDER_SEPARATOR
_RUN = "INSERT INTO belief_runs (self_id, t_ns, recorded_ns) VALUES (:s, :t, :r)"
# Periods to copy into own rows before a write that bypasses the rule (see BeliefRule.detach).
_HOLDER_OPEN = (
    "SELECT w.id FROM fact_keys k JOIN belief_follow w ON w.hkey = k.id "
    "AND w.to_ns IS NULL WHERE k.agent_id = :a"
)
_FOLLOWING_SELF = (
    "SELECT w.id FROM fact_keys k JOIN belief_follow w ON w.self_key = k.id WHERE k.agent_id = :a"
)


def holder_id(agent: str, *about: str) -> str:
    """The id of a (nested) belief holder: ``holder_id("Anne", "Sally") == "Anne>Sally"``."""
    return SEPARATOR.join((agent, *about))


#: 00_temp's scratch tables are emptied at each commit for the SQL clients whose triggers
#: create them; a store's session creates them first, without it (see :func:`_scratch`).
_EMPTIED_AT_COMMIT = " ON COMMIT DELETE ROWS"
#: A store's session vacuums its scratch tables after this many runs (PostgreSQL).
VACUUM_SCRATCH_EVERY = 64


@functools.cache
def _scratch(backend: str) -> list[str]:
    """PostgreSQL: the session's temporary scratch tables (00_temp), kept across commits.
    Emptying them at commit truncates every table and index, a cost taken while the run holds
    the rules' clock (the lock that serializes the runs of several robots; docs/beliefs.md): a
    store's run empties them itself (99_clear) and the store vacuums their dead rows after
    every :data:`VACUUM_SCRATCH_EVERY` runs, outside the transaction. Made once per session
    (:meth:`BeliefRule._prepare`)."""
    return split(sqltext.render("00_temp", backend).replace(_EMPTIED_AT_COMMIT, ""))


@functools.cache
def _materialize(backend: str) -> list[Any]:
    return [text(s) for s in split(sqltext.render("95_materialize", backend))]


class BeliefRule:
    """A store rule: after a self agent's write, the database propagates it to every other
    agent's beliefs."""

    #: It only sends statements and reads none of their results: the store may send them in
    #: the batch of the writes they follow (:mod:`toaster.db.writer.steps`).
    pipelined = True

    def __init__(self, store: Store) -> None:
        self.store = store
        self._runs = 0  # since the scratch tables were last vacuumed
        # The DBAPI connection whose session has the scratch tables, once the transaction
        # that made them committed (a rolled back one takes them away); until then, it and
        # that transaction's number (Store.transactions).
        self._scratch: weakref.ref[Any] | None = None
        self._making: tuple[weakref.ref[Any], int] | None = None

    def committed(self) -> None:
        """Vacuum the session's scratch tables every :data:`VACUUM_SCRATCH_EVERY` runs."""
        if self._making is not None and self._making[1] == self.store.transactions:
            self._scratch = self._making[0]
        self._making = None
        if self._runs >= VACUUM_SCRATCH_EVERY and self.store.db.vacuum_scratch():
            self._runs = 0

    def _prepare(self, conn: Connection) -> None:
        """The scratch tables exist (SQLite: in the schema; PostgreSQL: per session, made by
        its first run), and the transaction has their settings."""
        scratch = _scratch(conn.dialect.name)
        if not scratch:
            return
        cur = self.store.db.cursor()
        raw = cur.connection  # type: ignore[attr-defined]
        made = self._scratch is not None and self._scratch() is raw
        for statement in scratch:  # its settings (SET LOCAL) hold for one transaction
            if not made or not statement.startswith("CREATE "):
                cur.execute(statement)
        if not made:
            self._making = weakref.ref(raw), self.store.transactions

    def _insert_changed(self, conn: Connection, changes: ChangeSet) -> None:
        """The tick's self keys; refreshed ones with the values they held before the tick;
        each with the agent who made its change (``ChangeSet.actor_of``), if known."""
        rows: dict[int, tuple[Any, ...]] = {}
        keys = (
            [k for k, _ in changes.appeared]
            + [k for k, _, _ in changes.changed]
            + [k for k, _ in changes.ended]
        )
        for key_id in keys:
            rows[key_id] = (key_id, False, None, None, None, changes.actor_of(key_id))
        for key_id, _, held in changes.refreshed:
            rows[key_id] = (
                key_id,
                True,
                held.value_num,
                held.confidence,
                held.observability,
                changes.actor_of(key_id),
            )
        cur = self.store.db.cursor()
        if conn.dialect.name == "postgresql":
            cur.execute(
                "INSERT INTO belief_changed (key_id, refreshed, prev_num, prev_conf, prev_obs, "
                "actor_id) SELECT * FROM unnest(%b::bigint[], %b::boolean[], %b::float8[], "
                "%b::float8[], %b::float8[], %b::text[])",
                [list(column) for column in zip(*rows.values(), strict=True)],
            )
        else:
            cur.executemany(
                "INSERT INTO belief_changed (key_id, refreshed, prev_num, prev_conf, "
                "prev_obs, actor_id) VALUES (?, ?, ?, ?, ?, ?)",
                list(rows.values()),
            )

    def detach(self, conn: Connection, agent_id: str | None, *, keep: bool) -> None:
        """Before a write that bypasses the rule (a direct write to a holder, emptying an
        agent, changing who is self): copy the followed periods involving ``agent_id`` into
        its own rows. ``keep=False``: the agent's rows are about to be deleted, so its own
        periods are dropped instead (``agent_id`` None: every period). The groups of holders
        no longer hold (the next run forms them again)."""
        conn.execute(text(UNGROUP))
        if agent_id is None:
            conn.execute(text("DELETE FROM belief_follow"))
            return
        chosen = _FOLLOWING_SELF if not keep else f"{_HOLDER_OPEN} UNION {_FOLLOWING_SELF}"
        if conn.execute(text(f"SELECT EXISTS ({chosen})"), {"a": agent_id}).scalar():
            self._prepare(conn)
            conn.execute(text(f"INSERT INTO belief_mat (follow_id) {chosen}"), {"a": agent_id})
            for statement in _materialize(conn.dialect.name):
                conn.execute(statement)
        if not keep:
            conn.execute(
                text(
                    "DELETE FROM belief_follow WHERE hkey IN "
                    "(SELECT id FROM fact_keys WHERE agent_id = :a)"
                ),
                {"a": agent_id},
            )

    def __call__(self, conn: Connection, changes: ChangeSet) -> None:
        agents = self.store.agents()
        if changes.empty or not agents.get(changes.agent_id) or all(agents.values()):
            return  # not a self agent's change, or nobody else holds beliefs
        self._prepare(conn)
        self._insert_changed(conn, changes)
        self.store.db.cursor().execute(
            self.store.backend.named(_RUN),
            {"s": changes.agent_id, "t": changes.t_ns, "r": now_ns()},
        )
        self._runs += 1


def _check_sql(sql: str) -> bool:
    """True when ``sql`` names no bound parameter outside the known set (used by tests)."""
    return set(re.findall(r"(?<![:\w]):([a-z_]+)", sql)) <= {
        "self",
        "t",
        "source",
        "recorded",
        "phase",
        "everything",
        "moves",
    }
