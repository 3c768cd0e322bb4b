"""Reading facts: current beliefs, memory, full history, one value now or as of a time.

Every function takes a :class:`~toaster.db.Database` and returns :class:`~toaster.model.FactRow`
tuples. Ids are always bound parameters; only column names from a fixed list reach the SQL.
"""

from __future__ import annotations

from typing import Any

from toaster.model import FactRow

FACT_COLUMNS = ", ".join(FactRow._fields)
_FILTERABLE = ("agent_id", "subject_id", "subject_owner_id", "property", "property_type",
               "sub_property", "target_id", "target_owner_id", "value_text", "source")
_FILTER_ARGS = {"agent": "agent_id", "subject": "subject_id", "property": "property",
                "target": "target_id", "sub_property": "sub_property", "source": "source",
                "property_type": "property_type", "value": "value_text",
                "subject_owner": "subject_owner_id", "target_owner": "target_owner_id"}
_KEY_ONLY = ("k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, "
             "k.sub_property, k.target_id, k.target_owner_id")
_KEY_COLS = (f"{_KEY_ONLY}, f.value_text, f.value_num, f.confidence, f.observability, "
             "f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source")


def _where(filters: dict[str, Any], prefix: str = "") -> tuple[str, dict[str, Any]]:
    clauses, params = [], {}
    for arg, value in filters.items():
        if value is None or value == "NULL":
            continue
        column = _FILTER_ARGS[arg]
        if isinstance(value, list | tuple | set | frozenset):
            names = [f"{column}_{i}" for i in range(len(value))]
            clauses.append(f"{prefix}{column} IN ({', '.join(':' + n for n in names)})")
            params.update(zip(names, value, strict=True))
        else:
            clauses.append(f"{prefix}{column} = :{column}")
            params[column] = value
    return (" AND ".join(clauses) or "1 = 1"), params


def _rows(db: Any, sql: str, params: dict[str, Any]) -> list[FactRow]:
    # The driver's cursor directly: these reads are the API's hot path (as-of, point reads).
    with db.transaction():
        cur = db.cursor()
        cur.execute(db.backend.named(sql), params)
        return [FactRow(*row) for row in cur.fetchall()]


def _select(db: Any, view: str, filters: dict[str, Any], *, since: int | None,
            until: int | None, limit: int | None, order: str) -> list[FactRow]:
    where, params = _where(filters)
    if since is not None:  # intervals still true at or after `since`
        where += " AND (valid_to_ns IS NULL OR valid_to_ns > :since)"
        params["since"] = since
    if until is not None:  # intervals that started at or before `until`
        where += " AND valid_from_ns <= :until"
        params["until"] = until
    sql = f"SELECT {FACT_COLUMNS} FROM {view} WHERE {where} ORDER BY {order}"
    if limit is not None:
        sql += " LIMIT :limit"
        params["limit"] = int(limit)
    return _rows(db, sql, params)


def current_facts(db: Any, agent: str | None = None, *, limit: int | None = None,
                  **filters: Any) -> list[FactRow]:
    """Facts currently believed (open intervals), filtered by agent, subject, property, target,
    sub_property, source, value... (a list matches any of its items)."""
    return _select(db, "current_facts", {"agent": agent, **filters}, since=None, until=None,
                   limit=limit, order="agent_id, subject_id, property, target_id, fact_id")


def memory(db: Any, agent: str | None = None, *, since: int | None = None,
           until: int | None = None, limit: int | None = None, **filters: Any) -> list[FactRow]:
    """Past beliefs (closed intervals), oldest first; ``since``/``until`` keep intervals that
    overlap the window."""
    return _select(db, "memory", {"agent": agent, **filters}, since=since, until=until,
                   limit=limit, order="valid_from_ns, fact_id")


def history(db: Any, agent: str | None = None, *, since: int | None = None,
            until: int | None = None, limit: int | None = None, **filters: Any) -> list[FactRow]:
    """Every interval, current and past, oldest first (the timeline of the matching facts)."""
    return _select(db, "fact_history", {"agent": agent, **filters}, since=since, until=until,
                   limit=limit, order="valid_from_ns, fact_id")


def beliefs_at(db: Any, agent: str, t_ns: int, **filters: Any) -> list[FactRow]:
    """Everything ``agent`` believed at ``t_ns`` (as-of): one seek per fact key of the agent.

    A holder key that followed the self agent's key at ``t_ns`` (``belief_follow``) takes the
    self's interval then, clipped to the period, confidence x the period's ``pconf``."""
    backend = db.backend
    where, params = _where({"agent": agent, **filters}, prefix="k.")
    params["t"] = t_ns
    lo, hi = backend.least, backend.greatest
    own = (f"SELECT {_KEY_COLS}, k.id AS key_id FROM fact_keys k "
           f"{backend.as_of_join.format(key='k.id')} WHERE {where} "
           "AND (f.valid_to_ns IS NULL OR f.valid_to_ns > :t)")
    followed = (
        f"SELECT {_KEY_ONLY}, f.value_text, f.value_num, {lo}(1.0, f.confidence * w.pconf), "
        f"f.observability, {hi}(f.valid_from_ns, w.from_ns), CASE WHEN w.to_ns IS NULL THEN "
        "f.valid_to_ns WHEN f.valid_to_ns IS NULL THEN w.to_ns "
        f"ELSE {lo}(f.valid_to_ns, w.to_ns) END, f.recorded_ns, 'beliefs', k.id "
        "FROM fact_keys k JOIN belief_follow w ON w.hkey = k.id AND w.from_ns <= :t "
        f"AND (w.to_ns IS NULL OR w.to_ns > :t) {backend.as_of_join.format(key='w.self_key')} "
        f"WHERE {where} AND (f.valid_to_ns IS NULL OR f.valid_to_ns > :t)")
    sql = (f"SELECT {FACT_COLUMNS} FROM ({own} UNION ALL {followed}) AS held "
           "ORDER BY subject_id, property, target_id, key_id")
    return _rows(db, sql, params)


def fact_value(db: Any, agent: str, subject: str, property: str, target: str = "", *,
               at: int | None = None, sub_property: str | None = None,
               subject_owner: str | None = None,
               target_owner: str | None = None) -> FactRow | None:
    """The interval of one fact holding now (``at`` None) or at time ``at``; None if it does
    not hold. ``sub_property`` and owners None match any (the first match is returned)."""
    filters = {"agent": agent, "subject": subject, "property": property, "target": target,
               "sub_property": sub_property, "subject_owner": subject_owner,
               "target_owner": target_owner}
    if at is None:
        where, params = _where(filters)
        sql = f"SELECT {FACT_COLUMNS} FROM current_facts WHERE {where} ORDER BY key_id LIMIT 1"
        rows = _rows(db, sql, params)
    else:
        rows = beliefs_at(db, agent, at, **{k: v for k, v in filters.items() if k != "agent"})
    return rows[0] if rows else None
