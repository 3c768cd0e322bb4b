"""Rendering rows for people (rich tables, readable times) and for scripts (JSON, CSV)."""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

import click

from toaster.timeutil import format_ns

#: Columns shown in terminal tables per row type (JSON and CSV always carry every field).
TABLE_COLUMNS = {
    "FactRow": ("agent_id", "subject_id", "property", "target_id", "value_text", "value_num",
                "confidence", "valid_from_ns", "valid_to_ns", "source"),
    "EventRow": ("stamp_ns", "agent_id", "kind", "subject_id", "property", "target_id",
                 "value_text", "previous_text", "confidence", "source"),
}
_HEADERS = {"subject_id": "subject", "target_id": "target", "value_text": "value",
            "value_num": "num", "valid_from_ns": "from", "valid_to_ns": "to", "stamp_ns": "time",
            "agent_id": "agent", "previous_text": "previous", "entity_id": "entity"}


def output_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--json`` / ``--csv`` (default: a table on a terminal)."""
    func = click.option("--csv", "fmt", flag_value="csv", help="Comma-separated values.")(func)
    func = click.option("--json", "fmt", flag_value="json",
                        help="JSON lines, one object per row (times in ns).")(func)
    return func


def emit(rows: Sequence[Any], fmt: str | None, *, columns: Sequence[str] | None = None,
         title: str | None = None, empty: str = "(no rows)") -> None:
    """Print rows (NamedTuples or tuples with ``columns``) in the chosen format."""
    if columns is None:
        columns = list(rows[0]._fields) if rows else []
    records = [tuple(r) for r in rows]
    if fmt == "json":
        for record in records:
            click.echo(json.dumps(dict(zip(columns, record, strict=True)), default=str))
        return
    if fmt == "csv":
        writer = csv.writer(sys.stdout, lineterminator="\n")
        writer.writerow(columns)
        writer.writerows(records)
        return
    _table(rows, records, list(columns), title, empty)


def _cell(name: str, value: Any) -> str:
    if value is None:
        return "(current)" if name == "valid_to_ns" else ""
    if name.endswith("_ns") and isinstance(value, int):
        return format_ns(value)
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _table(rows: Sequence[Any], records: list[tuple[Any, ...]], columns: list[str],
           title: str | None, empty: str) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(width=None if sys.stdout.isatty() else 200, highlight=False)
    if not records:
        console.print(empty)
        return
    kind = type(rows[0]).__name__
    shown = [c for c in TABLE_COLUMNS.get(kind, columns) if c in columns]
    table = Table(title=title, show_lines=False)
    for name in shown:
        table.add_column(_HEADERS.get(name, name), overflow="fold")
    index = {name: columns.index(name) for name in shown}
    for record in records:
        table.add_row(*(_cell(name, record[index[name]]) for name in shown))
    console.print(table)


def say(message: str) -> None:
    """A status line for people (stderr, so that stdout stays clean for data)."""
    click.echo(message, err=True)
