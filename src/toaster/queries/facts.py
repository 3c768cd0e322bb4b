"""Reading facts: current beliefs, memory, full history, one value now or as of a time.

Every function takes a :class:`~toaster.db.Database` and returns :class:`~toaster.model.FactRow`
tuples. Ids are always bound parameters; only column names from a fixed list reach the SQL.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

from toaster.db.dialects import backend_for
from toaster.errors import InvalidInputError
from toaster.model import FactRow, NumberedInterval, check_id, check_text, shown
from toaster.queries import hotpath
from toaster.rules import sqltext
from toaster.timeutil import check_count, check_ns, check_optional_ns

if TYPE_CHECKING:
    from toaster.db.database import Database

FACT_COLUMNS = ", ".join(FactRow._fields)
_FILTERABLE = (
    "agent_id",
    "subject_id",
    "subject_owner_id",
    "property",
    "property_type",
    "sub_property",
    "target_id",
    "target_owner_id",
    "value_text",
    "source",
)
_FILTER_ARGS = {
    "agent": "agent_id",
    "subject": "subject_id",
    "property": "property",
    "target": "target_id",
    "sub_property": "sub_property",
    "source": "source",
    "property_type": "property_type",
    "value": "value_text",
    "subject_owner": "subject_owner_id",
    "target_owner": "target_owner_id",
}
_KEY_ONLY = (
    "k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, "
    "k.sub_property, k.target_id, k.target_owner_id"
)
_KEY_COLS = (
    f"{_KEY_ONLY}, f.value_text, f.value_num, f.confidence, f.observability, "
    "f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source"
)


def check_filter(arg: str, value: object) -> object:
    """``value`` if it is a filter the read path takes: None (any), text, or a list, tuple or
    set of texts (any of them); else a one-line error naming it. ``arg`` must be one of
    :data:`_FILTER_ARGS`."""
    if arg not in _FILTER_ARGS:
        msg = f"unknown filter {arg}={shown(value)}: filter by {', '.join(_FILTER_ARGS)}"
        raise InvalidInputError(msg)
    if isinstance(value, list | tuple | set | frozenset):
        for item in value:
            check_text(item, f"{arg} filter")
    elif value is not None:
        check_text(value, f"{arg} filter")
    return value


def _where(filters: dict[str, Any], prefix: str = "") -> tuple[str, dict[str, Any]]:
    clauses: list[str] = []
    params: dict[str, Any] = {}
    for arg, value in filters.items():
        if check_filter(arg, value) is None or value == "NULL":
            continue
        column = _FILTER_ARGS[arg]
        if isinstance(value, list | tuple | set | frozenset):
            names = [f"{column}_{i}" for i in range(len(value))]
            clauses.append(
                f"{prefix}{column} IN ({', '.join(':' + n for n in names)})" if names else "1 = 0"
            )  # an empty list matches nothing
            params.update(zip(names, value, strict=True))
        else:
            clauses.append(f"{prefix}{column} = :{column}")
            params[column] = value
    return (" AND ".join(clauses) or "1 = 1"), params


def _rows(db: Database, sql: str, params: dict[str, Any], *, raw: bool = False) -> list[Any]:
    # The driver's cursor directly: these reads are the API's hot path (point reads).
    rows = hotpath.fetch(db, db.backend.named(sql), params)
    return [tuple(row) for row in rows] if raw else list(map(FactRow._make, rows))


def _select(
    db: Database,
    view: str,
    filters: dict[str, Any],
    *,
    since: int | None,
    until: int | None,
    limit: int | None,
    order: str,
    extra: str = "",
) -> list[Any]:
    where, params = _where(filters)
    since, until = check_optional_ns(since, "since"), check_optional_ns(until, "until")
    limit = check_count(limit, "limit")
    if since is not None:  # intervals still true at or after `since`
        where += " AND (valid_to_ns IS NULL OR valid_to_ns > :since)"
        params["since"] = since
    if until is not None:  # intervals that started at or before `until`
        where += " AND valid_from_ns <= :until"
        params["until"] = until
    sql = f"SELECT {FACT_COLUMNS}{extra} FROM {view} WHERE {where} ORDER BY {order}"
    if limit is not None:
        sql += " LIMIT :limit"
        params["limit"] = limit
    return _rows(db, sql, params, raw=bool(extra))


def current_facts(
    db: Database,
    agent: str | Sequence[str] | None = None,
    *,
    limit: int | None = None,
    **filters: Any,
) -> list[FactRow]:
    """Facts currently believed (open intervals), filtered by agent, subject, property, target,
    sub_property, source, value... (a list matches any of its items)."""
    return _select(
        db,
        "current_facts",
        {"agent": agent, **filters},
        since=None,
        until=None,
        limit=limit,
        order="agent_id, subject_id, property, target_id, fact_id",
    )


def memory(
    db: Database,
    agent: str | Sequence[str] | None = None,
    *,
    since: int | None = None,
    until: int | None = None,
    limit: int | None = None,
    **filters: Any,
) -> list[FactRow]:
    """Past beliefs (closed intervals), oldest first; ``since``/``until`` keep intervals that
    overlap the window."""
    return _select(
        db,
        "memory",
        {"agent": agent, **filters},
        since=since,
        until=until,
        limit=limit,
        order="valid_from_ns, fact_id, agent_id",
    )


def history(
    db: Database,
    agent: str | Sequence[str] | None = None,
    *,
    since: int | None = None,
    until: int | None = None,
    limit: int | None = None,
    **filters: Any,
) -> list[FactRow]:
    """Every interval, current and past, oldest first (the timeline of the matching facts;
    an interval several agents share comes once per agent, by agent id)."""
    return _select(
        db,
        "fact_history",
        {"agent": agent, **filters},
        since=since,
        until=until,
        limit=limit,
        order="valid_from_ns, fact_id, agent_id",
    )


def _numbers_at(conf: str | None = None) -> str:
    """value_num, confidence, observability of interval ``f`` at ``:t``: those of its first
    sample after ``:t`` (``s``, see ``Backend.sample_join``) when there is one."""
    confidence = conf or "COALESCE(s.confidence, f.confidence)"
    return (
        "CASE WHEN s.confidence IS NULL THEN f.value_num ELSE s.value_num END AS value_num, "
        f"{confidence} AS confidence, "
        "COALESCE(s.observability, f.observability) AS observability"
    )


def _followed_numbers(backend: str) -> str:
    """The numbers of a followed interval at ``:t``: its sample's when there is one, the
    confidence as the holder sees it (the followed-period definition of
    :mod:`toaster.rules.sqltext`)."""
    conf = "{{followed_conf(COALESCE(s.confidence, f.confidence))}}"
    return _numbers_at(sqltext.expand(conf, backend))


def beliefs_at(db: Database, agent: str, t_ns: int, **filters: Any) -> list[FactRow]:
    """Everything ``agent`` believed at ``t_ns`` (as-of): one seek per fact key of the agent,
    numbers as they were then (within their tolerance, from ``fact_samples``).

    A holder key that followed the self agent's key at ``t_ns`` (``belief_follow``) takes the
    self's interval then, clipped to the period, confidence x the period's ``pconf``."""
    source = check_filter("source", filters.pop("source", None))
    value = check_filter("value", filters.pop("value", None))
    where, params = _where({"agent": check_id(agent, "agent id"), **filters}, prefix="k.")
    # value and source are the interval's (f); a followed one's source is 'beliefs', which
    # passes the filter or not as a whole
    value_where, value_params = _where({"value": value}, prefix="f.")
    own_source, source_params = _where({"source": source}, prefix="f.")
    params.update(value_params | source_params, t=check_ns(t_ns))
    if value_where != "1 = 1":
        where = f"{where} AND {value_where}"
    sql = _as_of_sql(db.backend.name, where, own_source, _passes("beliefs", source))
    return [FactRow._make(row[:-1]) for row in hotpath.fetch(db, sql, params, prepare=True)]


def _passes(value: str, allowed: object) -> bool:
    """Whether ``value`` passes the filter ``allowed`` (checked by :func:`check_filter`)."""
    if allowed is None or allowed == "NULL":
        return True
    if isinstance(allowed, list | tuple | set | frozenset):
        return value in allowed
    return value == allowed


@functools.lru_cache(maxsize=128)
def _as_of_sql(backend_name: str, where: str, own_source: str, followed: bool) -> str:
    """The as-of statement for one shape of filters, in the driver's parameter style (built
    once: the same text each call, which the driver keeps prepared).

    A compound ordered by the key's columns: each half walks the agent's keys in
    ``ix_fact_keys_agent_order``, so SQLite merges them without a sort (revision 0022)."""
    backend = backend_for(backend_name)
    samples = backend.sample_join.format(fact="f.id")
    sql = (
        f"SELECT {_KEY_ONLY}, f.value_text, {_numbers_at()}, f.valid_from_ns, "
        "f.valid_to_ns, f.recorded_ns, f.source, k.id AS key_id FROM fact_keys k "
        f"{backend.as_of_join.format(key='k.id')} {samples} WHERE {where} "
        "AND (f.valid_to_ns IS NULL OR f.valid_to_ns > :t)"
    )
    if own_source != "1 = 1":
        sql += f" AND {own_source}"
    if followed:
        sql += (
            f" UNION ALL SELECT {_KEY_ONLY}, f.value_text, {_followed_numbers(backend_name)}, "
            f"{sqltext.expand('{{followed_from}}, {{followed_to}}', backend_name)}, "
            "f.recorded_ns, 'beliefs', k.id FROM fact_keys k JOIN belief_follow w "
            "ON w.hkey = k.id AND w.from_ns <= :t AND (w.to_ns IS NULL OR w.to_ns > :t) "
            f"{backend.as_of_join.format(key='w.self_key')} {samples} WHERE {where} "
            "AND (f.valid_to_ns IS NULL OR f.valid_to_ns > :t) AND "
            f"{sqltext.expand('{{followed_facts}}', backend_name)}"
        )
    return backend.named(f"{sql} ORDER BY subject_id, property, target_id, key_id")


class SignalPoint(NamedTuple):
    """From ``t_ns`` on, one key's number and confidence (``None`` after its interval ends:
    the fact does not hold)."""

    agent_id: str
    subject_id: str
    property: str
    sub_property: str
    target_id: str
    t_ns: int
    value_num: float | None
    confidence: float | None


def numbered_history(
    db: Database,
    agent: str | Sequence[str] | None = None,
    *,
    since: int | None = None,
    until: int | None = None,
    **filters: Any,
) -> list[NumberedInterval]:
    """:func:`history` with each interval's stored refreshes (``Backend.samples``): what a
    reader needs for the number of a fact at any time of the window, not only its last."""
    rows = _select(
        db,
        "fact_history",
        {"agent": agent, **filters},
        since=since,
        until=until,
        limit=None,
        order="valid_from_ns, fact_id, agent_id",
        extra=", fact_id",
    )
    if not rows:
        return []
    samples: dict[int, list[tuple[int, float | None, float, float]]] = {}
    ids = sorted({row[-1] for row in rows})
    with db.transaction():
        cur = db.cursor()
        for start in range(0, len(ids), 500):
            chunk = ids[start : start + 500]
            names = {f"f{i}": fact_id for i, fact_id in enumerate(chunk)}
            cur.execute(
                db.backend.named(
                    "SELECT fact_id, until_ns, value_num, confidence, observability "
                    f"FROM {db.backend.samples} s WHERE "
                    f"fact_id IN ({', '.join(':' + n for n in names)}) ORDER BY fact_id, until_ns"
                ),
                names,
            )
            for fact_id, until_ns, value, conf, observability in cur.fetchall():
                samples.setdefault(fact_id, []).append((until_ns, value, conf, observability))
    out = []
    for *fields, fact_id in rows:
        row = FactRow(*fields)
        numbers = tuple(
            sample
            for sample in samples.get(fact_id, ())
            # a followed period's clipped start, or a sample past the interval's end
            if sample[0] > row.valid_from_ns
            and (row.valid_to_ns is None or sample[0] <= row.valid_to_ns)
        )
        out.append(NumberedInterval(row, numbers))
    return out


def signal(
    db: Database,
    agent: str | Sequence[str] | None = None,
    *,
    since: int | None = None,
    until: int | None = None,
    **filters: Any,
) -> list[SignalPoint]:
    """The numbers of the matching facts over time, as step points: each interval's start,
    each stored refresh (``Backend.samples``) and its end (``value_num`` None). Sorted by key,
    then time. The value at any time is the last point at or before it, within tolerance."""
    points: list[SignalPoint] = []
    for row, numbers in numbered_history(db, agent, since=since, until=until, **filters):
        head = (row.agent_id, row.subject_id, row.property, row.sub_property, row.target_id)
        start = row.valid_from_ns
        for until_ns, value, conf, _ in numbers:
            points.append(SignalPoint(*head, start, value, conf))
            start = until_ns
        points.append(SignalPoint(*head, start, row.value_num, row.confidence))
        if row.valid_to_ns is not None:
            points.append(SignalPoint(*head, row.valid_to_ns, None, None))
    points.sort(key=lambda p: (p[:5], p.t_ns))
    return points


def fact_value(
    db: Database,
    agent: str,
    subject: str,
    property: str,
    target: str = "",
    *,
    at: int | None = None,
    sub_property: str | None = None,
    subject_owner: str | None = None,
    target_owner: str | None = None,
) -> FactRow | None:
    """The interval of one fact holding now (``at`` None) or at time ``at``; None if it does
    not hold. ``sub_property`` and owners None match any (the first match is returned)."""
    filters = {
        "agent": check_id(agent, "agent id"),
        "subject": check_id(subject, "subject id"),
        "property": check_id(property, "property"),
        "target": target,
        "sub_property": sub_property,
        "subject_owner": subject_owner,
        "target_owner": target_owner,
    }
    if at is None:
        where, params = _where(filters)
        sql = f"SELECT {FACT_COLUMNS} FROM current_facts WHERE {where} ORDER BY key_id LIMIT 1"
        rows = _rows(db, sql, params)
    else:
        rows = beliefs_at(db, agent, at, **{k: v for k, v in filters.items() if k != "agent"})
    return rows[0] if rows else None
