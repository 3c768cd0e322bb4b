"""The revisions' loader of frozen belief triggers: it executes the copies under
``migrations/frozen/`` and renders nothing, so that an old revision imports no live rule code and
always creates the same objects (the live rendering and :func:`toaster.rules.triggers.freeze`
that writes the copies are in :mod:`toaster.rules.triggers`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from importlib import resources
from typing import Any

from sqlalchemy import Connection

#: The unit created last and dropped first: the driver, which calls the others (and holds the
#: inlined ones' statements: it is created again when one of them changes).
DRIVER = "pipeline"
_PLACEHOLDER = re.compile(r"\{\{unit:(\w+)\}\}")


def placeholder(unit: str) -> str:
    """Where the driver's frozen text takes ``unit``'s inlined statements (:func:`compose`)."""
    return f"{{{{unit:{unit}}}}}"


def compose(sql: list[str], inline: Callable[[str], list[str]]) -> list[str]:
    """``sql`` with each placeholder ``{{unit:<name>}}`` replaced by the unit's ``inline``
    statements, one a line."""
    return [_PLACEHOLDER.sub(lambda m: "\n".join(inline(m.group(1))), s) for s in sql]


def _frozen(*parts: str) -> Any:
    path = resources.files("toaster.migrations") / "frozen"
    for part in parts:
        path = path / part
    return json.loads(path.read_text(encoding="utf-8"))


def _execute(conn: Connection, sql: list[str]) -> None:
    cursor = conn.connection.dbapi_connection.cursor()  # type: ignore[union-attr]
    for statement in sql:
        cursor.execute(statement)


def run_frozen(conn: Connection, name: str, which: str) -> None:
    """Execute the frozen ``which`` (``create`` or ``drop``) statements of
    ``migrations/frozen/<name>.json`` for ``conn``'s backend (raw cursor: no parameter
    parsing). Used by the revisions 0007-0016."""
    _execute(conn, _frozen(f"{name}.json")[conn.dialect.name][which])


def swap_frozen(conn: Connection, old: str, new: str) -> None:
    """Drop the frozen triggers ``old`` and create the frozen ``new`` (see
    :func:`run_frozen`): a revision's upgrade, and with the two swapped its downgrade."""
    run_frozen(conn, old, "drop")
    run_frozen(conn, new, "create")


def manifest(revision: str) -> dict[str, str]:
    """The units installed at ``revision`` and the revision holding each one's file."""
    found: dict[str, str] = _frozen(f"{revision}_units.json")
    return found


def _unit(ref: str, unit: str, backend: str) -> dict[str, list[str]]:
    found: dict[str, list[str]] = _frozen(ref, f"{unit}.json")[backend]
    return found


def unit_statements(
    revision: str, backend: str, which: str, only: set[str] | None = None
) -> list[str]:
    """The ``which`` (``create`` or ``drop``) statements of the units of ``revision``'s
    manifest (``only``: of these), placeholders filled from the manifest, the driver last on
    create and first on drop."""
    refs = manifest(revision)
    order = sorted(
        only if only is not None else refs,
        key=lambda unit: (unit == DRIVER) == (which == "create"),
    )
    return compose(
        [s for unit in order for s in _unit(refs[unit], unit, backend)[which]],
        lambda unit: _unit(refs[unit], unit, backend).get("inline", []),
    )


def run_units(conn: Connection, revision: str, which: str) -> None:
    """Create or drop (``which``) every unit of ``revision``'s manifest."""
    _execute(conn, unit_statements(revision, conn.dialect.name, which))


def swap_units(conn: Connection, old: str, new: str) -> None:
    """Replace the units of manifest ``old`` by those of ``new``: the units whose file
    differs are dropped as ``old`` froze them and created as ``new`` did, and the driver too
    when one of them is inlined into it (a revision's upgrade, and with the two swapped its
    downgrade)."""
    backend = conn.dialect.name
    before, after = manifest(old), manifest(new)
    changed = {u for u in before.keys() | after.keys() if before.get(u) != after.get(u)}
    if any(
        _unit(refs[u], u, backend).get("inline")
        for refs in (before, after)
        for u in changed & refs.keys()
    ):
        changed.add(DRIVER)
    _execute(conn, unit_statements(old, backend, "drop", changed & before.keys()))
    _execute(conn, unit_statements(new, backend, "create", changed & after.keys()))


# -- The per-agent views and their write triggers (revision 0017) -----------------------------
_TEMPLATE = re.compile(r"\{\{(\w+)\}\}")


def agent_statements(
    name: str, backend: str, which: str, views: dict[str, str], num: int
) -> list[str]:
    """The frozen ``which`` templates of ``migrations/frozen/<name>.json`` for one agent:
    ``{{fact_table}}``, ``{{memory_table}}``, ``{{events_table}}`` filled with ``views`` (the
    quoted names) and ``{{num}}`` with the agent's number."""
    values = {**views, "num": str(int(num))}
    return [
        _TEMPLATE.sub(lambda m: values[m.group(1)], template)
        for template in _frozen(f"{name}.json")[backend][which]
    ]


def execute_frozen(conn: Connection, sql: list[str]) -> None:
    """Execute statements (:func:`agent_statements`) on the raw cursor."""
    _execute(conn, sql)
