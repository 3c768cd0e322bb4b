"""Exports of current facts, memory, full history and events to CSV, JSON lines and Parquet.

CSV and JSON lines need nothing beyond the standard library; Parquet needs the ``export`` extra
(pyarrow). Every file has one row per interval (or event) with the fields of
:class:`~toaster.model.FactRow` (or :class:`~toaster.model.EventRow`), times as integer
nanoseconds; :func:`read_rows` reads any of them back into the same typed rows and
:func:`read_frame` into the DataFrame :func:`toaster.queries.to_dataframe` builds.

CSV text cells that a spreadsheet would read as a formula (``=``, ``+``, ``-``, ``@``...) or
that start with ``'`` get one leading ``'`` (:func:`toaster.quoting.csv_text`); the readers
strip it. JSON lines are ASCII (:func:`toaster.quoting.json_line`).

Parquet keeps the types: text ``string``, integers ``int64`` (null where a field may be None:
an open interval's ``valid_to_ns``; pandas reads it as nullable ``Int64``, never as floats),
floats ``double``, and beside each ``X_ns`` time a column ``X`` of ``timestamp[ns, tz=UTC]``.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from toaster.errors import InvalidInputError, UnknownAgentError
from toaster.extras import require
from toaster.model import EventRow, FactRow, check_list, listed, shown
from toaster.quoting import csv_cells, csv_untext, json_line
from toaster.timeutil import check_optional_ns, format_ns

if TYPE_CHECKING:
    from toaster.db.database import Database

KINDS = ("facts", "memory", "history", "events")
FORMATS = ("csv", "jsonl", "parquet")
_SUFFIXES = {
    "csv": "csv",
    "jsonl": "jsonl",
    "ndjson": "jsonl",
    "json": "jsonl",
    "parquet": "parquet",
    "pq": "parquet",
}


class ExportResult(NamedTuple):
    """What :func:`export` wrote."""

    path: Path
    format: str
    rows: int


def row_type(kind: str) -> type[FactRow] | type[EventRow]:
    """The row type of an export kind (``events`` → EventRow, the others → FactRow)."""
    check_kind(kind)
    return EventRow if kind == "events" else FactRow


def check_kind(kind: str) -> str:
    """``kind`` if it is one of :data:`KINDS`, else a one-line error."""
    if kind not in KINDS:
        msg = f"unknown export kind {kind!r}: use one of {', '.join(KINDS)}"
        raise InvalidInputError(msg)
    return kind


def export_format(path: str | Path, format: str | None = None) -> str:
    """The format named or implied by the suffix (``.csv``, ``.jsonl``, ``.parquet``)."""
    name = (format or Path(path).suffix.lstrip(".")).lower()
    if name not in _SUFFIXES:
        shown = f"format {format!r}" if format else f"file suffix of {str(path)!r}"
        msg = f"unknown export {shown}: use one of {', '.join(FORMATS)}"
        raise InvalidInputError(msg)
    return _SUFFIXES[name]


def select_rows(
    db: Database,
    kind: str,
    *,
    agent: str | Sequence[str] | None = None,
    since: int | None = None,
    until: int | None = None,
    **filters: Any,
) -> list[FactRow] | list[EventRow]:
    """The rows an export of ``kind`` holds (filters as in get-info: subject, property, ...)."""
    from toaster import queries

    check_kind(kind)
    _check_agents(db, agent)
    since, until = check_optional_ns(since, "since"), check_optional_ns(until, "until")
    if since is not None and until is not None and until < since:
        msg = (
            f"empty time window: until {format_ns(until)} is before since "
            f"{format_ns(since)}; swap them"
        )
        raise InvalidInputError(msg)
    filters = {k: v for k, v in filters.items() if v is not None}
    if kind == "facts":
        if since is not None or until is not None:
            msg = (
                "current facts have no time window: export 'history' (or 'memory') to "
                "limit intervals to a window"
            )
            raise InvalidInputError(msg)
        return queries.current_facts(db, agent, **filters)
    read: dict[str, Callable[..., list[FactRow] | list[EventRow]]] = {
        "memory": queries.memory,
        "history": queries.history,
        "events": queries.events,
    }
    return read[kind](db, agent, since=since, until=until, **filters)


def _check_agents(db: Database, agent: str | Sequence[str] | None) -> None:
    if agent is None:
        return
    from toaster.queries import agents

    known = [a.id for a in agents(db)]
    for name in [agent] if isinstance(agent, str) else check_list(agent, "agent"):
        if name not in known:
            msg = f"unknown agent {shown(name)}: known agents are {listed(known)}"
            raise UnknownAgentError(msg)


def export(
    db: Database, kind: str, output: str | Path, *, format: str | None = None, **filters: Any
) -> ExportResult:
    """Write the rows of ``kind`` (facts, memory, history, events) matching ``filters``.

    Filters: agent, subject, property, target (lists match any), since, until (ns).
    """
    fmt = export_format(output, format)
    if fmt == "parquet":
        _pyarrow()
    rows = select_rows(db, kind, **filters)
    path = Path(output)
    write_rows(rows, row_type(kind), path, fmt)
    return ExportResult(path, fmt, len(rows))


def write_rows(rows: Sequence[NamedTuple], rtype: type[NamedTuple], path: Path, fmt: str) -> None:
    """Write typed rows to ``path`` in ``fmt`` (``csv``, ``jsonl`` or ``parquet``)."""
    fields = list(rtype._fields)
    if fmt == "csv":
        with path.open("w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(fields)
            writer.writerows(csv_cells("" if v is None else v for v in row) for row in rows)
    elif fmt == "jsonl":
        with path.open("w", encoding="utf-8") as handle:
            for row in rows:
                handle.write(json_line(dict(zip(fields, row, strict=True))) + "\n")
    else:
        _, pq = _pyarrow()
        pq.write_table(arrow_table(rows, rtype), path)


def arrow_table(rows: Sequence[NamedTuple], rtype: type[NamedTuple]) -> Any:
    """The rows as a typed ``pyarrow.Table`` (see the module docstring), with the pandas
    metadata that makes ``pandas.read_parquet`` give nullable ``Int64`` columns."""
    from toaster.queries.frames import field_kinds, time_columns

    pa, _ = _pyarrow()
    kinds = field_kinds(rtype)
    arrow = {str: pa.string(), int: pa.int64(), float: pa.float64(), bool: pa.bool_()}
    fields = list(rtype._fields)
    columns = {
        f: pa.array([row[i] for row in rows], arrow[kinds[f][0]]) for i, f in enumerate(fields)
    }
    stamp = pa.timestamp("ns", tz="UTC")
    for field, name in time_columns(fields).items():
        columns[name] = columns[field].cast(stamp)
    nullable_ints = [f for f in fields if kinds[f] == (int, True)]
    pandas = {
        "index_columns": [],
        "column_indexes": [],
        "creator": {"library": "toaster"},
        "columns": [
            {
                "name": f,
                "field_name": f,
                "pandas_type": "int64",
                "numpy_type": "Int64",
                "metadata": None,
            }
            for f in nullable_ints
        ],
    }
    table = pa.table(columns)
    return table.replace_schema_metadata({"pandas": json.dumps(pandas)})


def read_rows(path: str | Path, kind: str, format: str | None = None) -> list[Any]:
    """Read an export back into :class:`FactRow` or :class:`EventRow` tuples."""
    from toaster.queries.frames import field_kinds

    rtype = row_type(kind)
    fmt = export_format(path, format)
    path = Path(path)
    if fmt == "parquet":
        _, pq = _pyarrow()
        present = set(pq.read_schema(path).names)
        wanted = [f for f in rtype._fields if f in present]  # not the timestamp columns
        records: list[dict[str, Any]] = pq.read_table(path, columns=wanted).to_pylist()
    elif fmt == "jsonl":
        with path.open(encoding="utf-8") as handle:
            records = [json.loads(line) for line in handle if line.strip()]
    else:
        text = {f for f, (base, _) in field_kinds(rtype).items() if base is str}
        with path.open(newline="", encoding="utf-8") as handle:
            records = [
                {k: csv_untext(v) if k in text and v else v for k, v in rec.items()}
                for rec in csv.DictReader(handle)
            ]
    kinds = field_kinds(rtype)
    try:
        return [rtype(*(_typed(rec[f], kinds[f]) for f in rtype._fields)) for rec in records]
    except KeyError as exc:
        msg = f"{path.name}: column {exc.args[0]!r} is missing; is this a toaster {kind} export?"
        raise InvalidInputError(msg) from None


def read_frame(path: str | Path, kind: str, format: str | None = None) -> Any:
    """Read an export (CSV, JSON lines or Parquet) into a typed pandas DataFrame: the frame
    ``toaster.queries.to_dataframe(rows, times=True)`` gives for the exported rows (empty text
    stays ``""``, missing integers are ``<NA>``, times also as ``datetime64[ns, UTC]``)."""
    from toaster.queries.frames import to_dataframe

    rows = read_rows(path, kind, format)
    return to_dataframe(rows, None if rows else row_type(kind)._fields, times=True)


def _typed(value: Any, kind: tuple[type, bool]) -> Any:
    base, optional = kind
    if value is None or (value == "" and (optional or base is not str)):
        return None  # CSV cannot tell None from "": optional text reads back as None
    if base is int:
        return int(value)
    if base is float:
        return float(value)
    return str(value)


def _pyarrow() -> tuple[Any, Any]:
    require("export", "Parquet export")
    import pyarrow as pa  # type: ignore[import-untyped]  # (no py.typed)
    import pyarrow.parquet as pq  # type: ignore[import-untyped]

    return pa, pq
