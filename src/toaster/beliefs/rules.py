"""The belief rules: set-based SQL statements run in the transaction of every self write.

The statements live in the database (table ``belief_rules``, installed by migrations 0002 and
0003, one definition per backend). Per write (a *tick*) the rule runs a fixed number of
statements whatever the number of agents: the changed self keys go into a temporary table, one
recursive query computes who perceives what (rooms, containers, visibility, nested holders),
and one ``INSERT ... SELECT`` / ``UPDATE`` per kind of row writes what changes.

A holder whose belief equals the self's and who perceives its changes *follows* the self key
(``belief_follow``): the views show it the self's intervals and events, so such a change
writes no holder row. Rows are written only when a holder starts following (its own event,
its own interval closed), stops (it missed a change: its own interval continues the value it
held, a false belief), or when its perception confidence changes.
"""

from __future__ import annotations

import itertools
import re
from typing import TYPE_CHECKING, Any

from sqlalchemy import Connection, text

from toaster.beliefs import config as cfg
from toaster.db import catalog
from toaster.timeutil import now_ns

if TYPE_CHECKING:
    from toaster.db.store import ChangeSet, Store

SOURCE = "beliefs"
SEPARATOR = ">"
_STEPS_WRITE = ("35_freeze", "45_resolve", "50_keys", "45_resolve", "55_switch", "58_frozen",
                "60_plan", "70_events", "80_close", "85_refresh_rows")
# share_rows (default): a holder taking a change follows the self key; else it gets own rows.
_STEPS_SHARE = {True: ("90_follow", "92_repconf"), False: ("91_open", "92_repconf")}
# Periods to copy into own rows before a write that bypasses the rule (see BeliefRule.detach).
_HOLDER_OPEN = ("SELECT w.id FROM fact_keys k JOIN belief_follow w ON w.hkey = k.id "
                "AND w.to_ns IS NULL WHERE k.agent_id = :a")
_FOLLOWING_SELF = ("SELECT w.id FROM fact_keys k JOIN belief_follow w ON w.self_key = k.id "
                   "WHERE k.agent_id = :a")


def holder_id(agent: str, *about: str) -> str:
    """The id of a (nested) belief holder: ``holder_id("Anne", "Sally") == "Anne>Sally"``."""
    return SEPARATOR.join((agent, *about))


def _split(sql: str) -> list[str]:
    lines = [line for line in sql.splitlines() if not line.lstrip().startswith("--")]
    return [part.strip() for part in "\n".join(lines).split(";") if part.strip()]


def load_statements(conn: Connection) -> dict[str, list[Any]]:
    """The rule statements of this database's backend, by step (compiled once)."""
    rows = conn.execute(text("SELECT step, sql_text FROM belief_rules WHERE backend = :b"),
                        {"b": conn.dialect.name}).all()
    steps: dict[str, list[Any]] = {}
    for step, body in rows:
        parts = _split(body)
        steps[step] = parts if step == "00_temp" else [text(part) for part in parts]
    return steps


def ensure_holders(conn: Connection, depth: int, t_ns: int) -> int:
    """Register the nested holders ``A>B`` (and deeper, up to ``depth``) of every pair of
    first-order agents; return how many were created."""
    first = [row[0] for row in conn.execute(text(
        "SELECT id FROM agents WHERE NOT is_self AND id NOT IN "
        "(SELECT holder_id FROM belief_chain) ORDER BY id"))]
    known = {row[0] for row in conn.execute(text("SELECT DISTINCT holder_id FROM belief_chain"))}
    created = 0
    for length in range(2, depth + 1):
        for chain in itertools.product(first, repeat=length):
            if any(a == b for a, b in itertools.pairwise(chain)):
                continue
            holder = holder_id(*chain)
            if holder in known or holder in first:
                continue
            catalog.upsert_entity(conn, holder, "belief", "", "", is_self=False, agent=True,
                                  t_ns=t_ns)
            conn.execute(text("INSERT INTO belief_chain (holder_id, position, member_id) "
                              "VALUES (:h, :p, :m)"),
                         [{"h": holder, "p": i, "m": m} for i, m in enumerate(chain, 1)])
            created += 1
    return created


class BeliefRule:
    """A store rule: propagate a self agent's changes to every other agent's beliefs."""

    def __init__(self, store: Store) -> None:
        self.store = store
        self._steps: dict[str, list[Any]] | None = None
        self._agent_count: int | None = None

    def _insert_changed(self, conn: Connection, changes: ChangeSet) -> None:
        """The tick's self keys; refreshed ones with the values they held before the tick."""
        rows: dict[int, tuple[Any, ...]] = {}
        for item in (*changes.appeared, *changes.changed, *changes.ended):
            rows[item[0]] = (item[0], False, None, None, None)
        for key_id, _, held in changes.refreshed:
            rows[key_id] = (key_id, True, held.value_num, held.confidence, held.observability)
        cur = self.store.db.cursor()
        if conn.dialect.name == "postgresql":
            cur.execute(
                "INSERT INTO belief_changed (key_id, refreshed, prev_num, prev_conf, prev_obs) "
                "SELECT * FROM unnest(%s::bigint[], %s::boolean[], %s::float8[], %s::float8[], "
                "%s::float8[])", [list(column) for column in zip(*rows.values(), strict=True)])
        else:
            cur.executemany("INSERT INTO belief_changed VALUES (?, ?, ?, ?, ?)",
                            list(rows.values()))

    def _temp(self, conn: Connection, steps: dict[str, list[Any]]) -> None:
        cur = self.store.db.cursor()
        if conn.dialect.name == "postgresql":
            cur.execute(";\n".join(steps["00_temp"]))
        else:
            for part in steps["00_temp"]:
                cur.execute(part)

    def _clear(self, conn: Connection, steps: dict[str, list[Any]]) -> None:
        """Step 99_clear; on PostgreSQL its statements (no parameters) in one round trip."""
        if conn.dialect.name == "postgresql":
            self.store.db.cursor().execute(";\n".join(str(stmt) for stmt in steps["99_clear"]))
        else:
            self._run(conn, steps, ("99_clear",), {})

    def _run(self, conn: Connection, steps: dict[str, list[Any]], names: tuple[str, ...],
             params: dict[str, Any]) -> None:
        for name in names:
            for stmt in steps[name]:
                conn.execute(stmt, params)

    def _nested_holders(self, conn: Connection, steps: dict[str, list[Any]],
                        config: dict[str, Any], t_ns: int, params: dict[str, Any]) -> None:
        """Register missing ``A>B`` holders once someone perceives something (so that a
        database where nobody perceives anything keeps only its real agents)."""
        if config["depth"] < 2:
            return
        count = conn.execute(text("SELECT count(*) FROM agents")).scalar_one()
        if count == self._agent_count:
            return
        if conn.execute(text("SELECT 1 FROM belief_in LIMIT 1")).first() is None:
            return
        if ensure_holders(conn, int(config["depth"]), t_ns):
            conn.execute(text("DELETE FROM belief_seen"))
            conn.execute(text("DELETE FROM belief_in"))
            self._run(conn, steps, ("20_perceive", "30_changes"), params)
        self._agent_count = conn.execute(text("SELECT count(*) FROM agents")).scalar_one()

    def _statements(self, conn: Connection) -> dict[str, list[Any]]:
        if self._steps is None:
            self._steps = load_statements(conn)
        return self._steps

    def detach(self, conn: Connection, agent_id: str | None, *, keep: bool) -> None:
        """Before a write that bypasses the rule (a direct write to a holder, emptying an
        agent, changing who is self): copy the followed periods involving ``agent_id`` into
        its own rows. ``keep=False``: the agent's rows are about to be deleted, so its own
        periods are dropped instead (``agent_id`` None: every period)."""
        if agent_id is None:
            conn.execute(text("DELETE FROM belief_follow"))
            return
        chosen = _FOLLOWING_SELF if not keep else f"{_HOLDER_OPEN} UNION {_FOLLOWING_SELF}"
        if conn.execute(text(f"SELECT EXISTS ({chosen})"), {"a": agent_id}).scalar():
            steps = self._statements(conn)
            self._temp(conn, steps)
            conn.execute(text(f"INSERT INTO belief_mat (follow_id) {chosen}"), {"a": agent_id})
            self._run(conn, steps, ("95_materialize",), {})
        if not keep:
            conn.execute(text("DELETE FROM belief_follow WHERE hkey IN "
                              "(SELECT id FROM fact_keys WHERE agent_id = :a)"), {"a": agent_id})

    def __call__(self, conn: Connection, changes: ChangeSet) -> None:
        agents = self.store.agents()
        if changes.empty or not agents.get(changes.agent_id) or all(agents.values()):
            return  # not a self agent's change, or nobody else holds beliefs
        config = cfg.read(conn)
        if not config["enabled"]:
            return
        steps = self._statements(conn)
        facts = [*changes.appeared, *changes.changed, *changes.refreshed, *changes.ended]
        params = {"self": changes.agent_id, "t": changes.t_ns, "source": SOURCE,
                  "recorded": now_ns(), "phase": "around", "everything": 0}
        self._temp(conn, steps)
        self._insert_changed(conn, changes)
        self._run(conn, steps, ("10_focus", "20_perceive", "30_changes"), params)
        self._nested_holders(conn, steps, config, changes.t_ns, params)
        watched = cfg.perception_properties(config)
        if any(item[1].property in watched or item[1].property == config["closed"]
               for item in facts):
            for phase in ("before", "after"):
                self._run(conn, steps, ("20_perceive",), {**params, "phase": phase,
                                                          "everything": 1})
            self._run(conn, steps, ("40_refresh", "42_keep_max"), params)
        if conn.execute(_ANY_WORK).scalar():
            self._run(conn, steps, _STEPS_WRITE + _STEPS_SHARE[bool(config["share_rows"])],
                      params)
        self._clear(conn, steps)


#: Whether the write steps have anything to do: a holder takes a change (or sees something
#: again), or a holder follows a changed key (and, not perceiving the change, must stop). When
#: nobody perceives anything, as in a crowd replay with holders and no rooms, they are skipped.
_ANY_WORK = text(
    "SELECT EXISTS (SELECT 1 FROM belief_in) OR EXISTS (SELECT 1 FROM belief_changed b "
    "JOIN belief_follow w ON w.self_key = b.key_id AND w.to_ns IS NULL)")


def _check_sql(sql: str) -> bool:
    """True when ``sql`` names no bound parameter outside the known set (used by tests)."""
    return set(re.findall(r"(?<![:\w]):([a-z_]+)", sql)) <= {
        "self", "t", "source", "recorded", "phase", "everything"}
