"""Writes through an agent's views, as the original's scripts wrote its tables (revision 0017).

INSTEAD OF triggers turn a write on ``fact_table_<agent>`` or ``events_table_<agent>`` into a
``fact_inbox`` row, whose trigger applies it as the store does (intervals, events, the belief
rule), in the writer's transaction:

- ``INSERT INTO fact_table_X``: assert the row's fact for X from ``start`` (or
  ``valid_from_ns``);
- ``DELETE FROM fact_table_X``: retract each deleted row's fact at the wall clock's now (as
  ``Store.retract_facts`` without a time, and as the original's removal event);
- ``UPDATE fact_table_X SET "end" = T`` (or ``valid_to_ns``): retract at T; an UPDATE that
  changes anything else is refused (the original never updated a row either);
- ``INSERT INTO events_table_X``: a point event (the original's set_info EVENT).

A row may name a column by toaster's name or by the original's (:data:`SAME`), not both with
different values. The checks (:func:`checks`) are the same on both backends: PostgreSQL runs
them in two functions that every agent's triggers call with the agent's number; SQLite, which
has no functions, inlines them in each agent's triggers. The statements are templates: the
agent's number is ``{{num}}``, its views ``{{fact_table}}`` and ``{{events_table}}``
(:func:`toaster.db.views.agent_ddl` fills them).
"""

from __future__ import annotations

#: The placeholder of the agent's number.
NUM = "{{num}}"
#: A column a row may give under toaster's name or the original's: (toaster's, original's).
SAME = {
    "fact": (
        ("property", "predicate"),
        ("property_type", "propertytype"),
        ("value_text", "valuestring"),
        ("value_num", "valuedouble"),
        ("valid_from_ns", "start"),
    ),
    "events": (("property", "predicate"), ("property_type", "propertytype"), ("stamp_ns", "time")),
}
#: The columns of the fact view an UPDATE must leave alone (all but the end's two names).
KEPT = (
    "agent_id",
    "subject_id",
    "subject_owner_id",
    "property",
    "property_type",
    "sub_property",
    "target_id",
    "target_owner_id",
    "value_text",
    "value_num",
    "confidence",
    "observability",
    "valid_from_ns",
    "recorded_ns",
    "source",
    "fact_id",
    "key_id",
    "predicate",
    "propertytype",
    "valuetype",
    "valuestring",
    "valuedouble",
    "start",
)
#: PostgreSQL's trigger functions, by view.
FUNCTIONS = {"fact": "toaster_fact_table_write", "events": "toaster_events_table_write"}
_AGENT = f"(SELECT id FROM agents WHERE num = {NUM})"
_NOW = {
    "sqlite": "CAST((julianday('now') - 2440587.5) * 86400000000000 AS INTEGER)",
    "postgresql": "CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000000000 AS bigint)",
}
_DISTINCT = {"sqlite": "IS NOT", "postgresql": "IS DISTINCT FROM"}
_END = 'COALESCE(NEW.valid_to_ns, NULLIF(NEW."end", 0))'
#: (backends, condition, message): ``both`` or ``sqlite`` (PostgreSQL's typed view columns
#: refuse a value of the wrong type themselves, in one line).
Check = tuple[str, str, str]


def _either(old: str, new: str) -> str:
    return f"COALESCE(NEW.{old}, NEW.{new})"


def _not_a(kind: str, value: str) -> str:
    """SQLite: ``value`` is given and is no number (text that reads as one is, as a column's
    affinity would take it)."""
    return f"{value} IS NOT NULL AND NOT (CAST({value} AS {kind}) = {value})"


def checks(view: str, action: str) -> list[Check]:
    """The checks of an ``insert`` (fact or events view) or an ``update`` (fact view), in
    the order they run; the first that holds stops the write with its message. A ``delete``
    has none (its rows are the view's own)."""
    if action == "delete":
        return []
    if action == "update":
        changed = " OR ".join(f"NEW.{c} {{{{distinct}}}} OLD.{c}" for c in KEPT)
        return [
            (
                "both",
                f"{changed} OR {_END} IS NULL",
                'UPDATE only ends a fact: SET "end" (or valid_to_ns) to when it ended, in '
                "integer nanoseconds; to change a value, INSERT the new one with its start",
            ),
            ("sqlite", _not_a("INTEGER", _END), "end must be an integer (nanoseconds)"),
        ]
    found = [
        (
            "both",
            f"NEW.agent_id IS NOT NULL AND NEW.agent_id <> {_AGENT}",
            "agent_id names another agent: leave it out, or write that agent's own table",
        )
    ]
    if view == "events":
        found.append(
            (
                "both",
                "NEW.kind IS NOT NULL AND NEW.kind <> 'event'",
                "kind must be NULL or 'event': appeared, changed and ended events come from "
                "writing the agent's fact_table",
            )
        )
    found += [
        ("both", "COALESCE(NEW.subject_id, '') = ''", "give subject_id, the fact's subject"),
        (
            "both",
            "COALESCE(NEW.property, NEW.predicate, '') = ''",
            "give predicate (or property), the fact's property",
        ),
        *[
            (
                "both",
                f"NEW.{old} IS NOT NULL AND NEW.{new} IS NOT NULL AND NEW.{old} <> NEW.{new}",
                f"{new} and {old} are one column under two names: give one of them",
            )
            for old, new in SAME[view]
        ],
    ]
    own, word, what = (
        ("stamp_ns", "time", "when the event happened")
        if view == "events"
        else ("valid_from_ns", "start", "when the fact began")
    )
    start = _either(own, word)
    found += [
        ("both", f"{start} IS NULL", f"give {word} (or {own}): {what}, in integer nanoseconds"),
        ("sqlite", _not_a("INTEGER", start), f"{word} must be an integer (nanoseconds)"),
    ]
    numbers = ["value_num", "confidence", "observability"]
    if view == "fact":
        found += [
            (
                "both",
                'CAST(COALESCE(NEW.valid_to_ns, NEW."end", 0) AS REAL) <> 0',
                "end must be 0 or NULL: a fact table holds current facts (DELETE a row, or "
                'UPDATE its "end", to end one)',
            ),
            ("sqlite", _not_a("INTEGER", "NEW.valuetype"), "valueType must be 0 or 1"),
            (
                "both",
                "NEW.valuetype IS NOT NULL AND CAST(NEW.valuetype AS INTEGER) NOT IN (0, 1)",
                "valueType must be 0 (a text value) or 1 (a number in valueDouble)",
            ),
        ]
        numbers.insert(1, "valuedouble")
    found += [("sqlite", _not_a("REAL", f"NEW.{c}"), f"{c} must be a number") for c in numbers]
    return found


def _inbox(action: str, value_text: str, value_num: str, t_ns: str) -> str:
    return (
        "INSERT INTO fact_inbox (action, agent_id, subject_id, subject_owner_id, property, "
        "property_type, sub_property, target_id, target_owner_id, value_text, value_num, "
        f"confidence, observability, t_ns, source) VALUES ('{action}', {_AGENT}, "
        "NEW.subject_id, NEW.subject_owner_id, COALESCE(NEW.property, NEW.predicate), "
        "COALESCE(NEW.property_type, NEW.propertytype), NEW.sub_property, NEW.target_id, "
        f"NEW.target_owner_id, {value_text}, {value_num}, COALESCE(NEW.confidence, 1.0), "
        f"COALESCE(NEW.observability, 1.0), {t_ns}, COALESCE(NEW.source, 'sql'))"
    )


def _retract(t_ns: str) -> str:
    return (
        "INSERT INTO fact_inbox (action, agent_id, subject_id, subject_owner_id, property, "
        f"sub_property, target_id, target_owner_id, t_ns, source) VALUES ('retract', {_AGENT}, "
        "OLD.subject_id, OLD.subject_owner_id, OLD.property, OLD.sub_property, OLD.target_id, "
        f"OLD.target_owner_id, {t_ns}, 'sql')"
    )


def writes(view: str, action: str, backend: str) -> str:
    """The fact_inbox row of a write (``insert``, ``update``, ``delete``)."""
    if action == "delete":
        return _retract(_NOW[backend])
    if action == "update":
        return _retract(_END)
    if view == "events":
        return _inbox(
            "event",
            "COALESCE(NEW.value_text, 'true')",
            "NEW.value_num",
            _either("stamp_ns", "time"),
        )
    return _inbox(
        "assert",
        "COALESCE(NEW.value_text, NULLIF(NEW.valuestring, ''), 'true')",
        "COALESCE(NEW.value_num, "
        "CASE WHEN CAST(NEW.valuetype AS INTEGER) = 0 THEN NULL ELSE NEW.valuedouble END)",
        _either("valid_from_ns", "start"),
    )


def _quoted(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def _sqlite_checks(view: str, action: str) -> list[str]:
    return [
        f"SELECT RAISE(ABORT, {_quoted(f'{view}_table: {message}')}) WHERE "
        + condition.replace("{{distinct}}", _DISTINCT["sqlite"])
        + ";"
        for backends, condition, message in checks(view, action)
    ]


def _pg_checks(view: str, action: str) -> list[str]:
    found = []
    for backends, condition, message in checks(view, action):
        if backends != "both":
            continue
        if "%" in message:
            msg = f"a check's message holds '%': {message!r}"
            raise ValueError(msg)
        found += [
            f"IF {condition.replace('{{distinct}}', _DISTINCT['postgresql'])} THEN",
            f"RAISE EXCEPTION {_quoted('%: ' + message)}, TG_TABLE_NAME;",
            "END IF;",
        ]
    return found


#: The writes each view takes.
ACTIONS = {"fact": ("insert", "update", "delete"), "events": ("insert",)}


def sqlite_triggers() -> list[str]:
    """SQLite: an agent's triggers (templates), one per view and write."""
    return [
        f"CREATE TRIGGER toaster_agent_{NUM}_{view}_{action} INSTEAD OF {action.upper()} ON "
        f"{{{{{view}_table}}}} BEGIN\n"
        + "\n".join([*_sqlite_checks(view, action), writes(view, action, "sqlite") + ";"])
        + "\nEND"
        for view, actions in ACTIONS.items()
        for action in actions
    ]


def pg_triggers() -> list[str]:
    """PostgreSQL: an agent's triggers (templates), one per view, calling its function."""
    return [
        f"CREATE TRIGGER toaster_write INSTEAD OF {' OR '.join(a.upper() for a in actions)} ON "
        f"{{{{{view}_table}}}} FOR EACH ROW EXECUTE FUNCTION {FUNCTIONS[view]}('{NUM}')"
        for view, actions in ACTIONS.items()
    ]


def pg_functions() -> dict[str, list[str]]:
    """PostgreSQL: the ``create`` and ``drop`` statements of the functions the triggers of
    every agent call (its number the argument)."""
    create = []
    for view, actions in ACTIONS.items():
        body = []
        for action in actions:
            returned = "OLD" if action == "delete" else "NEW"
            body += [
                f"IF TG_OP = '{action.upper()}' THEN",
                *_pg_checks(view, action),
                writes(view, action, "postgresql").replace(NUM, "v_num") + ";",
                f"RETURN {returned};",
                "END IF;",
            ]
        lines = "\n".join(body).replace(NUM, "v_num")
        create.append(
            f"CREATE FUNCTION {FUNCTIONS[view]}() RETURNS trigger LANGUAGE plpgsql AS $fn$\n"
            "DECLARE v_num integer := TG_ARGV[0]::integer;\n"
            f"BEGIN\n{lines}\nRETURN NULL;\nEND\n$fn$"
        )
    drop = [f"DROP FUNCTION IF EXISTS {name}()" for name in FUNCTIONS.values()]
    return {"create": create, "drop": drop}
