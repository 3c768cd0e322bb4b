"""The triggers that make the database keep beliefs itself: DDL rendered per backend from
:data:`toaster.rules.pipeline.PIPELINE` and the ``inbox`` template, as *units*.

- ``belief_runs``: inserting ``(self_id, t_ns, recorded_ns)`` runs the belief rule over
  ``belief_changed`` (the store does it; see :mod:`toaster.rules.pipeline`).
- ``fact_inbox``: inserting a row writes one fact as the store would, then runs the rule
  (the write surface of plain SQL clients; docs/beliefs.md).

A unit (:func:`units`) is what a revision installs or replaces as one piece: each step instance
of the pipeline (``20_perceive_1_before`` is 20_perceive with its constants), ``00_temp``,
``99_clear``, ``inbox``, ``ungroup`` (the settings' and agents' triggers) and ``pipeline``
(the driver that runs the steps). On PostgreSQL a step is the function
``toaster_step_<unit>(p_self, p_t, p_recorded)`` that the run function calls (``PERFORM``). On
SQLite a step's statements are inlined into the driver's block triggers where its placeholder
``{{unit:<name>}}`` stands, when the driver is installed (``compose``): a trigger per step on
``belief_steps`` made every run slower, as every insert there runs each trigger's program
(docs/beliefs.md). The exception: a template of :data:`SHARED` (20_perceive, at five places)
is one trigger of its own, entered by a row naming the instance (revision 0027).

A migration installs frozen copies (``migrations/frozen/NNNN_units.json``, the manifest: each
unit's revision, and ``migrations/frozen/NNNN/<unit>.json``, written by :func:`freeze` for the
units that changed), never the live rendering, so that a revision always creates the same
objects; :mod:`toaster.migrations.frozen_triggers` loads them (``swap_units``; revisions
0007-0015 installed the whole set at once, ``NNNN_triggers.json``, ``run_frozen``). A change
of a template or of the pipeline needs a new revision that swaps the changed units; tests check
that the newest manifest is what the package renders and that a database at head holds it.
"""

from __future__ import annotations

import functools
import json
import re
import sys
from importlib import resources
from pathlib import Path
from typing import Any

from toaster.db.dialects import GUARD_MESSAGE
from toaster.migrations.frozen_triggers import DRIVER, compose, placeholder
from toaster.rules import sqltext
from toaster.rules.pipeline import (
    CLOCK,
    CLOCK_NS,
    MINE,
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
#: thresholds, and compiling it took far longer than running it (docs/beliefs.md). The step
#: functions need none of it: the run function's settings stay in force while it calls them.
_PG_SETTINGS = "SET join_collapse_limit = 1 SET plan_cache_mode = force_custom_plan SET jit = off"
_RUNS_GUARD = GUARD_MESSAGE.format(table="belief_runs")
BACKENDS = ("sqlite", "postgresql")
#: The scratch tables' units (before and after a run: they read no run values); the driver's
#: unit is the loader's DRIVER (created last, dropped first).
SCRATCH = ("00_temp", "99_clear")
#: One unit as frozen: per backend, its ``create`` and ``drop`` statements, and the statements
#: it puts where the driver holds its placeholder (``inline``, SQLite's steps).
Unit = dict[str, dict[str, list[str]]]


def _sql(name: str, backend: str, params: dict[str, str] | None = None) -> list[str]:
    rendered = sqltext.render(name, backend)
    return [bind(s, params if params is not None else RUN_PARAMS) for s in statements(rendered)]


def _quoted(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


# -- The step units ---------------------------------------------------------------------------
def unit_name(step: Step) -> str:
    """The unit of ``step``: its template, then its constants' values in the order of their
    names (``20_perceive_0_around``)."""
    return "_".join([step.name, *(re.sub(r"\W", "", value) for _, value in step.constants)])


@functools.cache
def step_units() -> dict[str, Step]:
    """The distinct step instances of the pipeline by unit name, in the order they first run."""
    found: dict[str, Step] = {}

    def walk(block: Block) -> None:
        for part in block.body:
            if isinstance(part, Block):
                walk(part)
            elif found.setdefault(unit_name(part), part) != part:
                msg = f"two steps render as the unit {unit_name(part)}"
                raise ValueError(msg)

    walk(PIPELINE)
    return found


#: PostgreSQL: a step function's parameters, and the run's columns bound to them.
_PG_ARGS = "p_self text, p_t bigint, p_recorded bigint"
_PG_PARAMS = {**RUN_PARAMS, "self": "p_self", "t": "p_t", "recorded": "p_recorded"}


@functools.cache
def _unit_sql(unit: str, backend: str) -> tuple[str, ...]:
    """The statements of a step or scratch unit (the scratch units read no run values)."""
    if unit in SCRATCH:
        return tuple(_sql(unit, backend, {}))
    step = step_units()[unit]
    params = _PG_PARAMS if backend == "postgresql" else RUN_PARAMS
    return tuple(_sql(step.name, backend, {**params, **dict(step.constants)}))


# -- PostgreSQL: plpgsql functions ----------------------------------------------------------
def _pg_call(unit: str, args: str = "NEW.self_id, NEW.t_ns, NEW.recorded_ns") -> list[str]:
    return [f"PERFORM toaster_step_{unit}({args});"] if _unit_sql(unit, "postgresql") else []


def _pg_block(block: Block) -> list[str]:
    body: list[str] = []
    if block is PIPELINE:  # the run locks its holders and takes their clock (pipeline.CLOCK)
        mine = {"mine": "id = ANY(mine)"}
        body += [
            # its robot's row first, alone: which holders are its own is read in the next
            # statement's snapshot, taken once the robot's run before it has committed (read
            # in the snapshot of a statement that then waited for that run, they missed the
            # people its facts had just named: their rows were written unlocked)
            "PERFORM 1 FROM holders WHERE id = NEW.self_id FOR NO KEY UPDATE;",
            f"mine := ARRAY({MINE} ORDER BY h.id FOR NO KEY UPDATE);",
            *[sqltext.expand(s.format(**mine), "postgresql") + ";" for s in CLOCK],
            f"NEW.t_ns := {CLOCK_NS.format(**mine)};",
        ]
    for part in block.body:
        body += _pg_block(part) if isinstance(part, Block) else _pg_call(unit_name(part))
    if block.condition is None:
        return body
    condition = sqltext.expand(block.condition, "postgresql")
    return [f"IF {condition} THEN", *body, "END IF;"]


def _pg_function(name: str, body: list[str], declare: str = "") -> str:
    lines = "\n".join(body)
    return (
        f"CREATE FUNCTION {name}() RETURNS trigger LANGUAGE plpgsql {_PG_SETTINGS} AS $fn$\n"
        f"{declare}BEGIN\n{lines}\nRETURN NULL;\nEND\n$fn$"
    )


def _pg_unit(unit: str) -> dict[str, list[str]]:
    sql = _unit_sql(unit, "postgresql")
    if not sql:
        return {"create": [], "drop": []}
    args = "" if unit in SCRATCH else _PG_ARGS
    types = "" if unit in SCRATCH else "text, bigint, bigint"
    lines = "\n".join(s + ";" for s in sql)
    return {
        "create": [
            f"CREATE FUNCTION toaster_step_{unit}({args}) RETURNS void "
            f"LANGUAGE plpgsql AS $fn$\nBEGIN\n{lines}\nEND\n$fn$"
        ],
        "drop": [f"DROP FUNCTION IF EXISTS toaster_step_{unit}({types})"],
    }


def _pg_pipeline() -> dict[str, list[str]]:
    run = _pg_function(
        "toaster_belief_run",
        [
            "IF current_setting('toaster.writer', true) IS DISTINCT FROM 'rules' THEN",
            f"RAISE EXCEPTION USING MESSAGE = {_quoted(_RUNS_GUARD)}, "
            "ERRCODE = 'insufficient_privilege';",
            "END IF;",
            *_pg_call("00_temp", ""),
            *_pg_block(PIPELINE),
            *_pg_call("99_clear", ""),
        ],
        declare="DECLARE mine text[];\n",  # the run's holders (pipeline.MINE)
    )
    return {
        "create": [
            run,
            "CREATE TRIGGER belief_runs_run BEFORE INSERT ON belief_runs "
            "FOR EACH ROW EXECUTE FUNCTION toaster_belief_run()",
        ],
        "drop": [
            "DROP TRIGGER IF EXISTS belief_runs_run ON belief_runs",
            "DROP FUNCTION IF EXISTS toaster_belief_run()",
        ],
    }


def _pg_inbox() -> dict[str, list[str]]:
    inbox_sql = sqltext.render("inbox", "postgresql")
    inbox = _pg_function(
        "toaster_fact_inbox",
        [
            "PERFORM set_config('toaster.writer', 'rules', true);",
            *_pg_call("00_temp", ""),
            *[s + ";" for s in statements(inbox_sql)],
            "PERFORM set_config('toaster.writer', COALESCE(previous_writer, ''), true);",
        ],
        declare="DECLARE previous_writer text := current_setting('toaster.writer', true);\n",
    )
    return {
        "create": [
            inbox,
            "CREATE TRIGGER fact_inbox_apply BEFORE INSERT ON fact_inbox "
            "FOR EACH ROW EXECUTE FUNCTION toaster_fact_inbox()",
        ],
        "drop": [
            "DROP TRIGGER IF EXISTS fact_inbox_apply ON fact_inbox",
            "DROP FUNCTION IF EXISTS toaster_fact_inbox()",
        ],
    }


# -- Both: what ends the groups of holders outside a run ---------------------------------------
#: A change of the settings or of the agents may change who perceives alike (96_regroup): the
#: next run forms the groups again (any client may write these tables). A change of the
#: agents also tells every store to re-read them.
_UNGROUP_ON = {"settings": UNGROUP, "agents": AGENTS_CHANGED}


#: PostgreSQL: a transaction that registers thousands of agents bumps the version once (each
#: update of the one store_state row in a transaction lengthens the row's version chain).
_PG_ONCE = {
    "agents": (
        "IF current_setting('toaster.agents_changed', true) IS DISTINCT FROM 'yes' "
        "OR (SELECT groups_for FROM store_state WHERE id = 1) IS NOT NULL "
        "OR (SELECT perceived_for FROM store_state WHERE id = 1) IS NOT NULL THEN",
        "PERFORM set_config('toaster.agents_changed', 'yes', true);",
    )
}


def _pg_ungroup() -> dict[str, list[str]]:
    def body(table: str, sql: str) -> list[str]:
        if table not in _PG_ONCE:
            return [f"{sql};"]
        condition, mark = _PG_ONCE[table]
        return [condition, f"{sql};", mark, "END IF;"]

    return {
        "create": [
            statement
            for table, sql in _UNGROUP_ON.items()
            for statement in (
                _pg_function(f"toaster_{table}_changed", body(table, sql)),
                f"CREATE TRIGGER {table}_ungroup AFTER INSERT OR UPDATE OR DELETE ON {table} "
                f"FOR EACH STATEMENT EXECUTE FUNCTION toaster_{table}_changed()",
            )
        ],
        "drop": [
            *[f"DROP TRIGGER IF EXISTS {t}_ungroup ON {t}" for t in _UNGROUP_ON],
            *[f"DROP FUNCTION IF EXISTS toaster_{t}_changed()" for t in _UNGROUP_ON],
        ],
    }


_ACTIONS = ("insert", "update", "delete")


def _sqlite_ungroup() -> dict[str, list[str]]:
    return {
        "create": [
            f"CREATE TRIGGER {table}_ungroup_{action} AFTER {action.upper()} ON "
            f"{table} BEGIN {sql}; END"
            for table, sql in _UNGROUP_ON.items()
            for action in _ACTIONS
        ],
        "drop": [f"DROP TRIGGER IF EXISTS {t}_ungroup_{a}" for t in _UNGROUP_ON for a in _ACTIONS],
    }


# -- SQLite: a trigger per block and per step -------------------------------------------------
def _sqlite_enter(block: Block) -> str:
    """The statement that runs ``block`` (its trigger fires on the inserted row); the
    pipeline's first moves the rules' clock and runs at its time (see pipeline.CLOCK)."""
    condition = sqltext.expand(block.condition or "1 = 1", "sqlite")
    t_ns = "NEW.t_ns"
    clock = ""
    if block is PIPELINE:
        mine = {"mine": f"id IN ({MINE})"}
        clock = "".join(
            f"{sqltext.expand(s.format(**mine), 'sqlite')} AND {condition};\n" for s in CLOCK
        )
        t_ns = CLOCK_NS.format(**mine)
    return (
        f"{clock}INSERT INTO belief_steps (block, self_id, t_ns, recorded_ns) SELECT "
        f"'{block.name}', NEW.self_id, {t_ns}, NEW.recorded_ns WHERE {condition};"
    )


def _sqlite_call(unit: str) -> list[str]:
    """The placeholder of the unit's statements (none when it has none)."""
    return [placeholder(unit)] if _unit_sql(unit, "sqlite") else []


def _sqlite_trigger(name: str, block: str, body: list[str]) -> str:
    lines = "\n".join(body)
    return (
        f"CREATE TRIGGER {name} AFTER INSERT ON belief_steps "
        f"WHEN NEW.block = '{block}' AND EXISTS (SELECT 1 FROM rule_writer) "
        f"BEGIN\n{lines}\nEND"
    )


def _sqlite_block(block: Block) -> str:
    body: list[str] = []
    for part in block.body:
        body += [_sqlite_enter(part)] if isinstance(part, Block) else _sqlite_call(unit_name(part))
    return _sqlite_trigger(f"belief_block_{block.name}", block.name, body)


#: SQLite: the templates run at several places of the pipeline that run as one trigger of their
#: own (``belief_step_<template>``), entered by a row naming the instance, its constants read
#: from that name. SQLite compiles a trigger's program once per outer statement but inlined
#: statements once per place, and a connection's first run compiles the whole pipeline:
#: 20_perceive's inlined copies were ~70 % of that (a fresh database's story, docs/beliefs.md).
SHARED = ("20_perceive",)


def _instances(template: str) -> dict[str, Step]:
    return {u: s for u, s in step_units().items() if s.name == template}


def _sqlite_unit(unit: str) -> dict[str, list[str]]:
    step = step_units().get(unit)
    if step is not None and step.name in SHARED:
        enter = (
            "INSERT INTO belief_steps (block, self_id, t_ns, recorded_ns) "
            f"VALUES ('{unit}', NEW.self_id, NEW.t_ns, NEW.recorded_ns);"
        )
        return {"create": [], "drop": [], "inline": [enter]}
    return {"create": [], "drop": [], "inline": [s + ";" for s in _unit_sql(unit, "sqlite")]}


def _sqlite_shared(template: str) -> dict[str, list[str]]:
    """The trigger of ``template``'s instances: each constant is a ``CASE`` over the name."""
    instances = _instances(template)
    names = {tuple(n for n, _ in step.constants) for step in instances.values()}
    if len(names) != 1:
        msg = f"the instances of {template} take different constants: {sorted(names)}"
        raise ValueError(msg)
    constants = {
        name: "(CASE NEW.block "
        + " ".join(f"WHEN '{u}' THEN {dict(s.constants)[name]}" for u, s in instances.items())
        + " END)"
        for name in names.pop()
    }
    body = [s + ";" for s in _sql(template, "sqlite", {**RUN_PARAMS, **constants})]
    blocks_in = ", ".join(f"'{u}'" for u in instances)
    name = f"belief_step_{template}"
    return {
        "create": [
            f"CREATE TRIGGER {name} AFTER INSERT ON belief_steps "
            f"WHEN NEW.block IN ({blocks_in}) AND EXISTS (SELECT 1 FROM rule_writer) "
            "BEGIN\n" + "\n".join(body) + "\nEND"
        ],
        "drop": [f"DROP TRIGGER IF EXISTS {name}"],
    }


def _sqlite_pipeline() -> dict[str, list[str]]:
    run = "\n".join(
        [
            f"SELECT RAISE(ABORT, {_quoted(_RUNS_GUARD)}) "
            "WHERE NOT EXISTS (SELECT 1 FROM rule_writer);",
            _sqlite_enter(PIPELINE),
            *_sqlite_call("99_clear"),
            "DELETE FROM belief_steps;",
            "SELECT RAISE(IGNORE);",
        ]
    )
    return {
        "create": [
            f"CREATE TRIGGER belief_runs_run BEFORE INSERT ON belief_runs BEGIN\n{run}\nEND",
            *[_sqlite_block(b) for b in blocks()],
        ],
        "drop": [
            f"DROP TRIGGER IF EXISTS {name}"
            for name in ("belief_runs_run", *[f"belief_block_{b.name}" for b in blocks()])
        ],
    }


def _sqlite_inbox() -> dict[str, list[str]]:
    inbox = "\n".join(
        [
            "INSERT OR IGNORE INTO rule_writer (id, holder) VALUES (1, 'inbox');",
            *[s + ";" for s in statements(sqltext.render("inbox", "sqlite"))],
            "DELETE FROM rule_writer WHERE holder = 'inbox';",
            "SELECT RAISE(IGNORE);",
        ]
    )
    return {
        "create": [
            f"CREATE TRIGGER fact_inbox_apply BEFORE INSERT ON fact_inbox BEGIN\n{inbox}\nEND"
        ],
        "drop": ["DROP TRIGGER IF EXISTS fact_inbox_apply"],
    }


# -- The units ------------------------------------------------------------------------------
def units() -> dict[str, Unit]:
    """Every unit as :func:`freeze` writes it, the pipeline last."""
    names = [SCRATCH[0], *step_units(), SCRATCH[1]]
    found: dict[str, Unit] = {
        unit: {"sqlite": _sqlite_unit(unit), "postgresql": _pg_unit(unit)} for unit in names
    }
    for template in SHARED:  # SQLite's trigger of the instances (PostgreSQL: their functions)
        found[template] = {
            "sqlite": _sqlite_shared(template),
            "postgresql": {"create": [], "drop": []},
        }
    blocks_named = {b.name for b in blocks()}
    if blocks_named & found.keys():  # a belief_steps row names one trigger only
        msg = f"blocks and steps share names: {sorted(blocks_named & found.keys())}"
        raise ValueError(msg)
    found["inbox"] = {"sqlite": _sqlite_inbox(), "postgresql": _pg_inbox()}
    found["ungroup"] = {"sqlite": _sqlite_ungroup(), "postgresql": _pg_ungroup()}
    found[DRIVER] = {"sqlite": _sqlite_pipeline(), "postgresql": _pg_pipeline()}
    return found


def ddl(backend: str) -> list[str]:
    """The CREATE statements of the triggers (and PostgreSQL's functions) of ``backend``."""
    if backend not in BACKENDS:
        msg = f"unsupported database backend {backend!r}"
        raise ValueError(msg)
    found = units()
    return compose(
        [s for unit in found.values() for s in unit[backend]["create"]],
        lambda unit: found[unit][backend]["inline"],
    )


def freeze(revision: str, folder: Path | None = None) -> list[str]:
    """Freeze the units for the new ``revision`` (``NNNN``) into ``folder`` (the package's
    ``migrations/frozen``): ``NNNN/<unit>.json`` for each unit that differs from the newest
    manifest before it, and the manifest ``NNNN_units.json``. Returns the units written (none,
    and nothing written, when nothing changed)."""
    if folder is None:
        folder = Path(str(resources.files("toaster.migrations"))) / "frozen"
    target = folder / revision
    for stale in [folder / f"{revision}_units.json", *target.glob("*.json")]:
        stale.unlink(missing_ok=True)  # an earlier freeze of this revision
    before = sorted(
        p.name for p in folder.glob("*_units.json") if p.name < f"{revision}_units.json"
    )
    old: dict[str, str] = (
        json.loads((folder / before[-1]).read_text(encoding="utf-8")) if (before) else {}
    )
    manifest: dict[str, str] = {}
    for unit, content in units().items():
        ref = old.get(unit)
        if ref is not None and _read(folder / ref / f"{unit}.json") == content:
            manifest[unit] = ref
            continue
        manifest[unit] = revision
        target.mkdir(exist_ok=True)
        _write(target / f"{unit}.json", content)
    if manifest != old:
        _write(folder / f"{revision}_units.json", manifest)
    if target.is_dir() and not any(target.iterdir()):
        target.rmdir()
    return [unit for unit, ref in manifest.items() if ref == revision]


def _read(path: Path) -> Any:
    return json.loads(path.read_text(encoding="utf-8"))


def _write(path: Path, content: object) -> None:
    with open(path, "w", encoding="utf-8") as out:
        json.dump(content, out, indent=1)
        out.write("\n")


if __name__ == "__main__":  # python -m toaster.rules.triggers freeze NNNN
    if len(sys.argv) != 3 or sys.argv[1] != "freeze" or not re.fullmatch(r"\d{4}", sys.argv[2]):
        sys.exit("usage: python -m toaster.rules.triggers freeze NNNN")
    written = freeze(sys.argv[2])
    print(f"froze {len(written)} unit(s) for {sys.argv[2]}: {', '.join(written) or 'none'}")
