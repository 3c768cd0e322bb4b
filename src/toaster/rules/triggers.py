"""The triggers that make the database keep beliefs itself: DDL rendered per backend from
:data:`toaster.rules.pipeline.PIPELINE` and the ``inbox`` template.

- ``belief_runs``: inserting ``(self_id, t_ns, recorded_ns)`` runs the belief rule over
  ``belief_changed`` (the store does it; see :mod:`toaster.rules.pipeline`).
- ``fact_inbox``: inserting a row writes one fact as the store would, then runs the rule
  (the write surface of plain SQL clients; docs/beliefs.md).

A migration installs a frozen copy of this DDL (``migrations/frozen/NNNN_triggers.json``,
written by :func:`freeze`), never the live rendering, so that a revision always creates the
same objects. A change of a template or of the pipeline needs a new revision that drops the
old triggers and installs newly frozen ones; tests check that the newest frozen copy is what
the package renders and that a database at head holds it.
"""

from __future__ import annotations

import json
import sys
from importlib import resources

from sqlalchemy import Connection

from toaster.db.dialects import GUARD_MESSAGE
from toaster.rules import sqltext
from toaster.rules.pipeline import (
    CLOCK,
    CLOCK_NS,
    PIPELINE,
    RUN_PARAMS,
    Block,
    Step,
    bind,
    blocks,
    statements,
)
from toaster.rules.sqltext import AGENTS_CHANGED, UNGROUP

#: Functions tuned as the rule's statements expect: the written join order, each statement
#: planned with the run's values (SQLite's plans are pinned by CROSS JOIN / INDEXED BY), and no
#: JIT: the recursive perception query's estimates (JSON settings, CTEs) passed JIT's cost
#: thresholds, and compiling it took ~3 s for a statement that runs in milliseconds.
_PG_SETTINGS = ("SET join_collapse_limit = 1 SET plan_cache_mode = force_custom_plan "
                "SET jit = off")
_RUNS_GUARD = GUARD_MESSAGE.format(table="belief_runs")


def _sql(name: str, backend: str, params: dict[str, str] | None = None) -> list[str]:
    rendered = sqltext.render(name, backend)
    return [bind(s, params if params is not None else RUN_PARAMS) for s in statements(rendered)]


def _step(step: Step, backend: str) -> list[str]:
    return _sql(step.name, backend, {**RUN_PARAMS, **dict(step.constants)})


def _quoted(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


# -- PostgreSQL: plpgsql functions ----------------------------------------------------------
def _pg_block(block: Block) -> list[str]:
    body: list[str] = []
    if block is PIPELINE:  # the run takes the rules' clock (see pipeline.CLOCK)
        body += [sqltext.expand(CLOCK, "postgresql") + ";",
                 f"NEW.t_ns := {CLOCK_NS};"]
    for part in block.body:
        body += _pg_block(part) if isinstance(part, Block) else [
            s + ";" for s in _step(part, "postgresql")]
    if block.condition is None:
        return body
    condition = sqltext.expand(block.condition, "postgresql")
    return [f"IF {condition} THEN", *body, "END IF;"]


def _pg_function(name: str, body: list[str], declare: str = "") -> str:
    lines = "\n".join(body)
    return (f"CREATE FUNCTION {name}() RETURNS trigger LANGUAGE plpgsql {_PG_SETTINGS} AS $fn$\n"
            f"{declare}BEGIN\n{lines}\nRETURN NULL;\nEND\n$fn$")


def _postgresql() -> list[str]:
    temp = [s + ";" for s in _sql("00_temp", "postgresql")]
    clear = [s + ";" for s in _sql("99_clear", "postgresql")]
    run = _pg_function("toaster_belief_run", [
        "IF current_setting('toaster.writer', true) IS DISTINCT FROM 'rules' THEN",
        f"RAISE EXCEPTION USING MESSAGE = {_quoted(_RUNS_GUARD)}, "
        "ERRCODE = 'insufficient_privilege';",
        "END IF;", *temp, *_pg_block(PIPELINE), *clear])
    inbox_sql = sqltext.render("inbox", "postgresql")
    inbox = _pg_function("toaster_fact_inbox", [
        "PERFORM set_config('toaster.writer', 'rules', true);", *temp,
        *[s + ";" for s in statements(inbox_sql)],
        "PERFORM set_config('toaster.writer', COALESCE(previous_writer, ''), true);"],
        declare="DECLARE previous_writer text := current_setting('toaster.writer', true);\n")
    return [run, "CREATE TRIGGER belief_runs_run BEFORE INSERT ON belief_runs FOR EACH ROW "
                 "EXECUTE FUNCTION toaster_belief_run()",
            inbox, "CREATE TRIGGER fact_inbox_apply BEFORE INSERT ON fact_inbox FOR EACH ROW "
                   "EXECUTE FUNCTION toaster_fact_inbox()", *_pg_ungroup()]


# -- Both: what ends the groups of holders outside a run ---------------------------------------
#: A change of the settings or of the agents may change who perceives alike (96_regroup): the
#: next run forms the groups again (any client may write these tables). A change of the
#: agents also tells every store to re-read them.
_UNGROUP_ON = {"settings": UNGROUP, "agents": AGENTS_CHANGED}


#: PostgreSQL: a transaction that registers thousands of agents bumps the version once (each
#: update of the one store_state row in a transaction lengthens the row's version chain).
_PG_ONCE = {"agents": (
    "IF current_setting('toaster.agents_changed', true) IS DISTINCT FROM 'yes' "
    "OR (SELECT groups_for FROM store_state WHERE id = 1) IS NOT NULL THEN",
    "PERFORM set_config('toaster.agents_changed', 'yes', true);")}


def _pg_ungroup() -> list[str]:
    def body(table: str, sql: str) -> list[str]:
        if table not in _PG_ONCE:
            return [f"{sql};"]
        condition, mark = _PG_ONCE[table]
        return [condition, f"{sql};", mark, "END IF;"]

    return [statement for table, sql in _UNGROUP_ON.items() for statement in (
        _pg_function(f"toaster_{table}_changed", body(table, sql)),
        f"CREATE TRIGGER {table}_ungroup AFTER INSERT OR UPDATE OR DELETE ON {table} "
        f"FOR EACH STATEMENT EXECUTE FUNCTION toaster_{table}_changed()")]


def _sqlite_ungroup() -> list[str]:
    return [f"CREATE TRIGGER {table}_ungroup_{action} AFTER {action.upper()} ON {table} "
            f"BEGIN {sql}; END"
            for table, sql in _UNGROUP_ON.items() for action in ("insert", "update", "delete")]


# -- SQLite: a trigger per block ------------------------------------------------------------
def _sqlite_enter(block: Block) -> str:
    """The statement that runs ``block`` (its trigger fires on the inserted row); the
    pipeline's first moves the rules' clock and runs at its time (see pipeline.CLOCK)."""
    condition = sqltext.expand(block.condition or "1 = 1", "sqlite")
    t_ns = "NEW.t_ns"
    clock = ""
    if block is PIPELINE:
        clock = f"{sqltext.expand(CLOCK, 'sqlite')} AND {condition};\n"
        t_ns = CLOCK_NS
    return (f"{clock}INSERT INTO belief_steps (block, self_id, t_ns, recorded_ns) SELECT "
            f"'{block.name}', NEW.self_id, {t_ns}, NEW.recorded_ns WHERE {condition};")


def _sqlite_block(block: Block) -> str:
    body: list[str] = []
    for part in block.body:
        body += [_sqlite_enter(part)] if isinstance(part, Block) else [
            s + ";" for s in _step(part, "sqlite")]
    lines = "\n".join(body)
    return (f"CREATE TRIGGER belief_block_{block.name} AFTER INSERT ON belief_steps "
            f"WHEN NEW.block = '{block.name}' AND EXISTS (SELECT 1 FROM rule_writer) "
            f"BEGIN\n{lines}\nEND")


def _sqlite() -> list[str]:
    clear = [s + ";" for s in _sql("99_clear", "sqlite")]
    run = "\n".join([
        f"SELECT RAISE(ABORT, {_quoted(_RUNS_GUARD)}) "
        "WHERE NOT EXISTS (SELECT 1 FROM rule_writer);",
        _sqlite_enter(PIPELINE), *clear, "DELETE FROM belief_steps;", "SELECT RAISE(IGNORE);"])
    inbox = "\n".join([
        "INSERT OR IGNORE INTO rule_writer (id, holder) VALUES (1, 'inbox');",
        *[s + ";" for s in statements(sqltext.render("inbox", "sqlite"))],
        "DELETE FROM rule_writer WHERE holder = 'inbox';", "SELECT RAISE(IGNORE);"])
    return [f"CREATE TRIGGER belief_runs_run BEFORE INSERT ON belief_runs BEGIN\n{run}\nEND",
            *[_sqlite_block(b) for b in blocks()],
            f"CREATE TRIGGER fact_inbox_apply BEFORE INSERT ON fact_inbox BEGIN\n{inbox}\nEND",
            *_sqlite_ungroup()]


def ddl(backend: str) -> list[str]:
    """The CREATE statements of the triggers (and PostgreSQL's functions) of ``backend``."""
    if backend == "postgresql":
        return _postgresql()
    if backend == "sqlite":
        return _sqlite()
    msg = f"unsupported database backend {backend!r}"
    raise ValueError(msg)


def drop_ddl(backend: str) -> list[str]:
    """The DROP statements undoing :func:`ddl`."""
    if backend == "postgresql":
        return ["DROP TRIGGER IF EXISTS belief_runs_run ON belief_runs",
                "DROP TRIGGER IF EXISTS fact_inbox_apply ON fact_inbox",
                "DROP FUNCTION IF EXISTS toaster_belief_run()",
                "DROP FUNCTION IF EXISTS toaster_fact_inbox()",
                *[f"DROP TRIGGER IF EXISTS {t}_ungroup ON {t}" for t in _UNGROUP_ON],
                *[f"DROP FUNCTION IF EXISTS toaster_{t}_changed()" for t in _UNGROUP_ON]]
    return [f"DROP TRIGGER IF EXISTS {name}" for name in (
        "belief_runs_run", "fact_inbox_apply", *[f"belief_block_{b.name}" for b in blocks()],
        *[f"{t}_ungroup_{a}" for t in _UNGROUP_ON for a in ("insert", "update", "delete")])]


def frozen() -> dict[str, dict[str, list[str]]]:
    """What :func:`freeze` writes: per backend, the ``create`` and ``drop`` statements."""
    return {backend: {"create": ddl(backend), "drop": drop_ddl(backend)}
            for backend in ("sqlite", "postgresql")}


def freeze(path: str) -> None:
    """Write :func:`frozen` to ``path`` (JSON), for a new revision to install."""
    with open(path, "w", encoding="utf-8") as out:
        json.dump(frozen(), out, indent=1)
        out.write("\n")


def run_frozen(conn: Connection, name: str, which: str) -> None:
    """Execute the frozen ``which`` (``create`` or ``drop``) statements of
    ``migrations/frozen/<name>.json`` for ``conn``'s backend (raw cursor: no parameter
    parsing). Used by the revisions."""
    text = (resources.files("toaster.migrations") / "frozen" / f"{name}.json").read_text(
        encoding="utf-8")
    cursor = conn.connection.dbapi_connection.cursor()  # type: ignore[union-attr]
    for statement in json.loads(text)[conn.dialect.name][which]:
        cursor.execute(statement)


def swap_frozen(conn: Connection, old: str, new: str) -> None:
    """Drop the frozen triggers ``old`` and create the frozen ``new`` (see
    :func:`run_frozen`): a revision's upgrade, and with the two swapped its downgrade."""
    run_frozen(conn, old, "drop")
    run_frozen(conn, new, "create")


if __name__ == "__main__":  # python -m toaster.rules.triggers FILE.json
    freeze(sys.argv[1])
