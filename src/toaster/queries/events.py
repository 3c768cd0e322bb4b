"""Reading events: every change of an agent's beliefs, and user-recorded events."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from sqlalchemy import text

from toaster.model import EventRow, check_list, check_text
from toaster.queries.facts import _where
from toaster.timeutil import check_count, check_optional_ns

if TYPE_CHECKING:
    from toaster.db.database import Database

EVENT_COLUMNS = ", ".join(EventRow._fields)


def events(
    db: Database,
    agent: str | None = None,
    *,
    since: int | None = None,
    until: int | None = None,
    kind: str | list[str] | None = None,
    limit: int | None = None,
    newest_first: bool = False,
    **filters: Any,
) -> list[EventRow]:
    """Events in ``[since, until]`` (both inclusive), oldest first unless ``newest_first``
    (one event of several agents, a shared belief's, comes once per agent, by agent id).

    Filters: agent, subject, property, target, sub_property, source, value (lists match any).
    """
    where, params = _where({"agent": agent, **filters})
    since, until = check_optional_ns(since, "since"), check_optional_ns(until, "until")
    limit = check_count(limit, "limit")
    if kind is not None:
        kinds = (
            [check_text(kind, "kind")]
            if isinstance(kind, str)
            else [check_text(k, "kind") for k in check_list(kind, "kind")]
        )
        names = [f"kind_{i}" for i in range(len(kinds))]
        where += f" AND kind IN ({', '.join(':' + n for n in names)})" if names else " AND 1 = 0"
        params.update(zip(names, kinds, strict=True))
    if since is not None:
        where += " AND stamp_ns >= :since"
        params["since"] = since
    if until is not None:
        where += " AND stamp_ns <= :until"
        params["until"] = until
    order = "DESC" if newest_first else "ASC"
    sql = (
        f"SELECT {EVENT_COLUMNS} FROM event_log WHERE {where} "
        f"ORDER BY stamp_ns {order}, id {order}, agent_id {order}"
    )
    if limit is not None:
        sql += " LIMIT :limit"
        params["limit"] = limit
    with db.transaction() as conn:
        return [EventRow(*row) for row in conn.execute(text(sql), params)]
