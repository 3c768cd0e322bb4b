"""The belief rule's SQL: one template per step (``rules/sql/NN_step.sql``), rendered per backend.

A template is the step's SQL with *macros* where the backends differ: ``{{name}}`` or
``{{name(argument)}}``, replaced by plain text substitution (no SQL contains ``{{``; ``$`` in
JSON paths and ``:name`` parameters pass untouched). Every macro is declared in
:data:`MACROS` (one dict per backend) or :data:`COMMON` (the same on both, may use the
former); an unknown one fails loudly. ``{{#backend}} ... {{/backend}}`` keeps a section for
one backend only: the few places where the plans really differ (20_perceive reads the
perception facts through a LATERAL subquery on PostgreSQL) or where PostgreSQL needs an
extra statement (00_temp's planner settings, 20_perceive's ``ANALYZE``).

The followed period (a holder's belief shown as the self's interval clipped to a
``belief_follow`` period, confidence x ``pconf``, and the self's events in it) is defined
once, by the ``followed_*`` macros of :data:`FOLLOWED`: the readable views (:func:`views`,
frozen into migration 0003 at each change), the as-of query
(:func:`toaster.queries.facts.beliefs_at`) and step ``95_materialize`` all expand them.

Settings are read through the view ``belief_settings`` (stored value or default, migration
0006) by the ``setting*`` macros only.
"""

from __future__ import annotations

import functools
import re
from importlib import resources

from toaster.model import MAX_ID_BYTES, SPACES

#: The steps of the rule, in order (see :class:`toaster.rules.hook.BeliefRule` for when each
#: one runs).
STEPS = (
    "00_temp",
    "10_focus",
    "12_moves",
    "13_late",
    "15_ungroup",
    "19_settled",
    "20_perceive",
    "20_reuse",
    "21_remember",
    "30_changes",
    "32_expand",
    "35_freeze",
    "40_refresh",
    "42_keep_max",
    "45_resolve",
    "50_keys",
    "55_switch",
    "58_frozen",
    "60_plan",
    "70_events",
    "80_close",
    "85_refresh_rows",
    "90_follow",
    "91_open",
    "92_repconf",
    "94_keep_groups",
    "95_materialize",
    "96_regroup",
    "97_unsettle",
    "98_settle",
    "99_clear",
)

#: Where a function-like macro puts its argument.
ARG = "<arg>"

#: The dialect macros: everything that differs between the backends' rule SQL.
MACROS: dict[str, dict[str, str]] = {
    "sqlite": {
        "lo": "MIN",  # two-argument scalar forms
        "hi": "MAX",
        "is_distinct": "IS NOT",
        "insert_or_ignore": "INSERT OR IGNORE",
        "on_conflict_ignore": "",
        # SQLite plans the temporary tables without statistics: CROSS JOIN keeps the written
        # join order, INDEXED BY the open-interval indexes.
        "pinned_join": "CROSS JOIN",
        "open_fact": "INDEXED BY uq_facts_open_key",
        "open_follow": "INDEXED BY uq_belief_follow_open_hkey",
        # A holder's keys about a target (the statistics favour the identity index's agent
        # prefix: a scan of all the holder's keys per entity).
        "keys_by_target": "INDEXED BY ix_fact_keys_target",
        # Bound parameters in a select list take their type from the column on SQLite.
        "as_int8": ARG,
        "as_text": ARG,
        # The time now in ns (a write's recorded_ns; ms resolution on SQLite 3.40).
        "now_ns": "CAST((julianday('now') - 2440587.5) * 86400000000000 AS INTEGER)",
        # JSON settings: a list's items, a map's (key, value) pairs, a string.
        "setting_list": f"json_each({{{{setting({ARG})}}}})",
        "setting_map": f"json_each({{{{setting({ARG})}}}})",
        "setting_text": f"json_extract({{{{setting({ARG})}}}}, '$')",
        # The entity is not hidden in a closed container (the CTE ``hidden``).
        "not_hidden": f"{ARG} NOT IN (SELECT e FROM hidden)",
        # A map of lists as (key, value) rows.
        "setting_pairs": (
            f"(SELECT m.key AS key, l.value AS value FROM "
            f"json_each({{{{setting({ARG})}}}}) AS m, json_each(m.value) AS l)"
        ),
    },
    "postgresql": {
        "lo": "LEAST",
        "hi": "GREATEST",
        "is_distinct": "IS DISTINCT FROM",
        "insert_or_ignore": "INSERT",
        "on_conflict_ignore": "ON CONFLICT DO NOTHING",
        "pinned_join": "JOIN",  # the order is pinned by join_collapse_limit = 1 (00_temp)
        "open_fact": "",
        "open_follow": "",
        "keys_by_target": "",
        "as_int8": f"CAST({ARG} AS bigint)",
        "as_text": f"CAST({ARG} AS text)",
        "now_ns": "CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000000000 AS bigint)",
        "setting_list": f"json_array_elements_text(CAST({{{{setting({ARG})}}}} AS json))",
        "setting_map": f"json_each_text(CAST({{{{setting({ARG})}}}} AS json))",
        "setting_text": f"(CAST({{{{setting({ARG})}}}} AS json) #>> '{{}}')",
        # An anti-join: NOT IN over the recursive CTE (estimated at a million rows) was planned
        # as a scan of it per row, and the joins around it as nested loops.
        "not_hidden": f"NOT EXISTS (SELECT 1 FROM hidden WHERE hidden.e = {ARG})",
        "setting_pairs": (
            f"(SELECT m.key AS key, l.value AS value FROM "
            f"json_each_text(CAST({{{{setting({ARG})}}}} AS json)) AS m, "
            f"json_array_elements_text(CAST(m.value AS json)) AS l(value))"
        ),
    },
}

#: The followed period: ``w`` a ``belief_follow`` row, ``f`` an interval of its self key,
#: ``e`` an event of it.
FOLLOWED = {
    # A confidence as the holder sees it (the argument: the self's confidence).
    "followed_conf": f"{{{{lo}}}}(1.0, {ARG} * w.pconf)",
    # The self's interval clipped to the period.
    "followed_from": "{{hi}}(f.valid_from_ns, w.from_ns)",
    "followed_to": (
        "CASE WHEN w.to_ns IS NULL THEN f.valid_to_ns "
        "WHEN f.valid_to_ns IS NULL THEN w.to_ns "
        "ELSE {{lo}}(f.valid_to_ns, w.to_ns) END"
    ),
    # The self's intervals shown in the period (an empty closed period shows none).
    "followed_facts": (
        "(w.to_ns IS NULL OR (f.valid_from_ns < w.to_ns AND w.to_ns > w.from_ns)) "
        "AND (f.valid_to_ns IS NULL OR f.valid_to_ns > w.from_ns)"
    ),
    # The self's events shown in the period (not the point events of kind 'event').
    "followed_events": (
        "e.kind <> 'event' AND e.stamp_ns >= w.events_from_ns "
        "AND (w.events_to_ns IS NULL OR e.stamp_ns <= w.events_to_ns)"
    ),
}

#: The write surface (template ``inbox``): ``NEW`` is the ``fact_inbox`` row.
INBOX = {
    # The row's key (NULL key fields mean '').
    "inbox_key": (
        "(SELECT id FROM fact_keys WHERE agent_id = NEW.agent_id "
        "AND subject_id = NEW.subject_id "
        "AND subject_owner_id = COALESCE(NEW.subject_owner_id, '') "
        "AND property = NEW.property AND sub_property = COALESCE(NEW.sub_property, '') "
        "AND target_id = COALESCE(NEW.target_id, '') "
        "AND target_owner_id = COALESCE(NEW.target_owner_id, ''))"
    ),
    # The row's open interval, as the target of an UPDATE (SQLite: through a subquery, as it
    # allows no INDEXED BY on an UPDATE's table inside a trigger).
    "inbox_open_interval": (
        "{{#sqlite}}id = (SELECT f.id FROM facts f {{open_fact}} "
        "WHERE f.key_id = {{inbox_key}} AND f.valid_to_ns IS NULL){{/sqlite}}"
        "{{#postgresql}}key_id = {{inbox_key}} AND valid_to_ns IS NULL"
        "{{/postgresql}}"
    ),
    # The key's last interval (intervals of a key never overlap) starts or ends after NEW.
    "inbox_later": (
        "(SELECT COALESCE(f.valid_to_ns, f.valid_from_ns) FROM facts f "
        "WHERE f.key_id = {{inbox_key}} ORDER BY f.valid_from_ns DESC LIMIT 1) "
        "> NEW.t_ns"
    ),
    "inbox_self": "EXISTS (SELECT 1 FROM agents WHERE id = NEW.agent_id AND is_self)",
    # The open interval f moved numbers only.
    "inbox_renumbered": (
        "(f.value_num {{is_distinct}} NEW.value_num "
        "OR f.confidence <> NEW.confidence "
        "OR f.observability <> NEW.observability)"
    ),
    # The current facts a retract ends (k, f): NULL or 'NULL' fields match any, as the
    # original's wildcard (Store.retract_facts).
    "inbox_match": (
        "fact_keys k JOIN facts f {{open_fact}} ON f.key_id = k.id AND f.valid_to_ns IS NULL "
        "WHERE k.agent_id = NEW.agent_id AND k.property = NEW.property"
        + "".join(
            f" AND (NEW.{c} IS NULL OR NEW.{c} = 'NULL' OR k.{c} = NEW.{c})"
            for c in (
                "subject_id",
                "target_id",
                "sub_property",
                "subject_owner_id",
                "target_owner_id",
            )
        )
    ),
}

#: The id fields of an inbox row that a write stores (checked as ``model.check_id`` checks
#: ids; agent_id and actor_id must name registered agents already).
INBOX_IDS = (
    "subject_id",
    "property",
    "target_id",
    "sub_property",
    "subject_owner_id",
    "target_owner_id",
)
_BAD_ID = (
    "NEW.action <> 'retract' AND NEW.{c} IS NOT NULL AND NEW.{c} <> '' AND "
    "({trim}(NEW.{c}, {spaces}) = '' OR {size} > " + str(MAX_ID_BYTES) + "{nul})"
)
_ID_RULE = (
    "ids must not be only spaces, hold NUL or be over " + str(MAX_ID_BYTES) + " bytes of UTF-8"
)
_ID_FIX = "give a shorter id or one with a visible character"
#: One check per id field (template ``inbox``), each naming its field (and, on PostgreSQL,
#: the value): the rule of ``model.check_id``.
INBOX_ID_CHECKS = {
    "sqlite": "\n".join(
        f"SELECT RAISE(ABORT, 'fact_inbox: invalid {c}: {_ID_RULE}: {_ID_FIX}') WHERE "
        + _BAD_ID.format(
            c=c,
            trim="TRIM",
            spaces="char(" + ",".join(str(ord(ch)) for ch in SPACES) + ")",
            size=f"LENGTH(CAST(NEW.{c} AS BLOB))",
            nul=f" OR INSTR(CAST(NEW.{c} AS BLOB), x'00') > 0",
        )
        + ";"
        for c in INBOX_IDS
    ),
    "postgresql": "\n".join(
        "IF "
        + _BAD_ID.format(
            c=c,
            trim="BTRIM",
            spaces="||".join(f"chr({ord(ch)})" for ch in SPACES),
            size=f"OCTET_LENGTH(NEW.{c})",
            nul="",  # PostgreSQL's text holds no NUL
        )
        + f" THEN\n  RAISE EXCEPTION 'fact_inbox: invalid {c} %L: {_ID_RULE}: {_ID_FIX}', "
        f"NEW.{c};\nEND IF;"
        for c in INBOX_IDS
    ),
}

for _backend, _checks in INBOX_ID_CHECKS.items():
    MACROS[_backend]["inbox_id_checks"] = _checks

#: The nested holders (templates ``holders`` / ``holders_seen``): the agents and depth they
#: were registered for.
HOLDERS = {
    "holders_basis": (
        "(SELECT CAST(count(*) AS text) || ':' || CAST(COALESCE(MAX(num), 0) AS "
        "text) FROM agents) || ':' || {{setting(depth)}}"
    ),
}

#: The self agent holds (an open interval of) the key identical to the holder key ``<arg>``.
SELF_HOLDS = {
    "self_holds": (
        "SELECT 1 FROM fact_keys sk JOIN facts sf ON sf.key_id = sk.id AND sf.valid_to_ns IS NULL "
        f"WHERE sk.agent_id = :self AND sk.subject_id = {ARG}.subject_id "
        f"AND sk.subject_owner_id = {ARG}.subject_owner_id AND sk.property = {ARG}.property "
        f"AND sk.sub_property = {ARG}.sub_property AND sk.target_id = {ARG}.target_id "
        f"AND sk.target_owner_id = {ARG}.target_owner_id"
    ),
}

#: The perception inputs: the properties whose self facts decide who perceives what (rooms,
#: containment, visibility, attention) or what is seen again (closed containers). A run whose
#: changes hold none of them (and no actor) perceives as the last one did: it reuses the kept
#: perception (``belief_perceived``, step 21_remember). One list for every place that needs
#: it (the macro ``perception``: the pipeline's test of a perception change, the kept
#: perception's horizon).
PERCEPTION = (
    "SELECT value FROM {{setting_list(copresence)}}",
    "SELECT value FROM {{setting_list(containment)}}",
    "SELECT key FROM {{setting_map(visibility)}}",
    "SELECT x.value FROM {{setting_pairs(attention)}} AS x",
    "SELECT {{setting_text(closed)}}",
)
#: 20_perceive's settings, as CTEs (its two statements on SQLite read them). Attention (setting
#: attention: copresence property -> attention properties): being in the room is not enough,
#: the holder must attend (a fact HOLDER P ENTITY, HOLDER P ROOM or a targetless HOLDER P, for
#: one of the properties). No entry: copresence alone.
PERCEPTION_SETTINGS = {
    "perception_settings": (
        "cfg_room(p) AS (SELECT value FROM {{setting_list(copresence)}}),\n"
        "cfg_in(p) AS (SELECT value FROM {{setting_list(containment)}}),\n"
        "cfg_vis(p, side) AS (SELECT key, value FROM {{setting_map(visibility)}}),\n"
        "cfg_att(p, a) AS (SELECT x.key, x.value FROM {{setting_pairs(attention)}} AS x),\n"
        "cfg_depth(d) AS (SELECT CAST({{setting(depth)}} AS INTEGER))"
    ),
}
#: The kept perception (``belief_perceived``, ``belief_settled``) and the self agent it is of
#: (``store_state.perceived_for``); it ends with the groups (below), and a run computes it again.
KEPT = {
    "perception": " UNION ALL ".join(PERCEPTION),
    # The latest boundary (start or end) of the self agent <arg>'s perception facts: beyond
    # the run's time, perception would change without a write (a fact written ahead of the
    # clock, with no run), and nothing is kept.
    "perception_horizon": (
        "(SELECT MAX((SELECT COALESCE(f.valid_to_ns, f.valid_from_ns) FROM facts f "
        "WHERE f.key_id = k.id ORDER BY f.valid_from_ns DESC, f.id DESC LIMIT 1)) "
        f"FROM fact_keys k WHERE k.agent_id = {ARG} AND k.property IN ({{{{perception}}}}))"
    ),
}
#: Ends the groups of holders outside a run (a write that changes a holder's followed keys,
#: the settings, the agents): the next run forms them again (96_regroup). The kept perception
#: ends with them (it covers the holders computed while they hold).
UNGROUP = "UPDATE store_state SET groups_for = NULL, perceived_for = NULL WHERE id = 1"
#: A write to ``agents`` (any client): the groups end and every store re-reads its agents
#: (``store_state.agents_version``, read at the start of each store write).
AGENTS_CHANGED = (
    "UPDATE store_state SET groups_for = NULL, perceived_for = NULL, "
    "agents_version = agents_version + 1 WHERE id = 1"
)

#: Groups of holders that perceive alike (96_regroup).
GROUPS = {
    "ungroup": UNGROUP,
    # The groups were ended (by this run, or by a write since the last run).
    "groups_ended": "(SELECT groups_for FROM store_state WHERE id = 1) IS NULL",
    # The holder ``<arg>`` is computed: it heads a group or belongs to none.
    "not_member": (f"{ARG} NOT IN (SELECT holder_id FROM belief_groups WHERE rep_id <> holder_id)"),
}

#: The macros that are the same on both backends.
COMMON = {
    **INBOX,
    **HOLDERS,
    **SELF_HOLDS,
    **GROUPS,
    **KEPT,
    **PERCEPTION_SETTINGS,
    # A beliefs setting as stored (JSON text), or its default.
    "setting": f"(SELECT value_json FROM belief_settings WHERE key = '{ARG}')",
    **FOLLOWED,
}

_SECTION = re.compile(r"\{\{#(\w+)\}\}(.*?)\{\{/\1\}\}", re.DOTALL)
_MACRO = re.compile(r"\{\{(\w+)(?:\(([^{}]*?)\))?\}\}")


def _macro(backend: str, match: re.Match[str]) -> str:
    name, arg = match.group(1), match.group(2)
    body = MACROS[backend].get(name, COMMON.get(name))
    if body is None:
        msg = f"unknown SQL macro {{{{{name}}}}}"
        raise ValueError(msg)
    if (arg is None) == (ARG in body):
        msg = (
            f"SQL macro {{{{{name}}}}} takes an argument"
            if arg is None
            else f"SQL macro {{{{{name}}}}} takes no argument"
        )
        raise ValueError(msg)
    return body if arg is None else body.replace(ARG, arg)


@functools.cache
def expand(sql: str, backend: str) -> str:
    """``sql`` with its sections and macros rendered for ``backend`` (cached)."""
    if backend not in MACROS:
        msg = f"unsupported database backend {backend!r}"
        raise ValueError(msg)

    def section(match: re.Match[str]) -> str:
        if match.group(1) not in MACROS:
            msg = f"unknown backend section {{{{#{match.group(1)}}}}}"
            raise ValueError(msg)
        return match.group(2) if match.group(1) == backend else ""

    text = _SECTION.sub(section, sql)
    for _ in range(4):  # macros may use macros (and sections)
        rendered = _SECTION.sub(section, _MACRO.sub(lambda m: _macro(backend, m), text))
        if rendered == text:
            break
        text = rendered
    if "{{" in text or "}}" in text:
        msg = f"unrendered SQL macro in {text[max(text.find('{{'), 0) :][:60]!r}"
        raise ValueError(msg)
    return text


#: Templates the triggers use besides the steps: registering nested holders, and the write
#: surface (see :mod:`toaster.rules.pipeline`).
TRIGGER_TEMPLATES = ("holders", "reperceive", "holders_seen", "inbox")


def template(step: str) -> str:
    """The template of ``step`` (``{{materialize}}``: the text of step 95_materialize)."""
    if step not in STEPS and step not in TRIGGER_TEMPLATES:
        msg = f"unknown belief rule step {step!r}"
        raise ValueError(msg)
    text = (resources.files("toaster.rules") / "sql" / f"{step}.sql").read_text(encoding="utf-8")
    return (
        text.replace("{{materialize}}", template("95_materialize"))
        if ("{{materialize}}" in text)
        else text
    )


@functools.cache
def render(step: str, backend: str) -> str:
    """The SQL of ``step`` for ``backend`` (``"sqlite"`` or ``"postgresql"``)."""
    return expand(template(step), backend)


_KEY = (
    "k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, "
    "k.sub_property, k.target_id, k.target_owner_id"
)
_OWN = (
    f"SELECT {_KEY}, f.value_text, f.value_num, f.confidence, f.observability, "
    "f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source, f.id AS fact_id, "
    "k.id AS key_id FROM facts f JOIN fact_keys k ON k.id = f.key_id"
)
_FOLLOWED_FACTS = (
    f"SELECT {_KEY}, f.value_text, f.value_num, {{{{followed_conf(f.confidence)}}}}, "
    "f.observability, {{followed_from}}, {{followed_to}}, f.recorded_ns, 'beliefs', f.id, k.id "
    "FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey "
    "JOIN facts f ON f.key_id = w.self_key AND {{followed_facts}}"
)
_EVENT_KEY = (
    "k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, "
    "k.target_id, k.target_owner_id"
)
_OWN_EVENTS = (
    f"SELECT e.id, e.agent_id, e.kind, e.stamp_ns, {_EVENT_KEY}, e.value_text, e.value_num, "
    "e.confidence, e.observability, e.previous_text, e.source, e.recorded_ns, e.key_id "
    "FROM events e JOIN fact_keys k ON k.id = e.key_id"
)
_FOLLOWED_EVENTS = (
    f"SELECT e.id, k.agent_id, e.kind, e.stamp_ns, {_EVENT_KEY}, e.value_text, e.value_num, "
    "{{followed_conf(e.confidence)}}, e.observability, e.previous_text, 'beliefs', "
    "e.recorded_ns, k.id "
    "FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey "
    "JOIN events e ON e.key_id = w.self_key AND {{followed_events}}"
)


def views(backend: str) -> list[tuple[str, str]]:
    """The readable views (name, body): own rows, then followed periods as the holders' rows.

    Migrations freeze these bodies (a revision never imports live view text);
    ``tests/rules/test_sqltext.py`` checks that the database's views are these."""
    followed = expand(_FOLLOWED_FACTS, backend)
    return [
        ("fact_history", f"{_OWN} UNION ALL {followed}"),
        (
            "current_facts",
            f"{_OWN} WHERE f.valid_to_ns IS NULL UNION ALL {followed} "
            "AND w.to_ns IS NULL AND f.valid_to_ns IS NULL",
        ),
        (
            "memory",
            f"{_OWN} WHERE f.valid_to_ns IS NOT NULL UNION ALL {followed} "
            "AND (w.to_ns IS NOT NULL OR f.valid_to_ns IS NOT NULL)",
        ),
        ("event_log", f"{_OWN_EVENTS} UNION ALL {expand(_FOLLOWED_EVENTS, backend)}"),
    ]
