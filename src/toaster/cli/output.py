"""Rendering rows for people and for scripts: one definition of the listing options (``--limit``,
``--json``, ``--csv``) and of how rows are printed.

On a terminal rows are a rich table with readable times; piped (stdout not a terminal) the
same columns and cells are plain tab-separated lines under one header line; ``--json`` (JSON
lines) and ``--csv`` carry every field, times in integer ns. Tables show every column of a
row's identity (agent, subject and its owner, property, sub-property, target and its owner);
on a terminal an owner or sub-property column empty in every row is left out.

Data is quoted by :mod:`toaster.quoting`: terminal and tab-separated cells show every character
(control characters escaped, no rich markup), text cells of CSV and tab-separated lines that a
spreadsheet would read as a formula start with ``'``, JSON lines are ASCII.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import click

from toaster.quoting import csv_line, csv_text, json_line, visible
from toaster.timeutil import format_ns

if TYPE_CHECKING:
    from toaster.timeutil import TimeFrame

#: Columns shown in tables per row type (JSON and CSV always carry every field).
TABLE_COLUMNS = {
    "FactRow": (
        "agent_id",
        "subject_id",
        "subject_owner_id",
        "property",
        "sub_property",
        "target_id",
        "target_owner_id",
        "value_text",
        "value_num",
        "confidence",
        "valid_from_ns",
        "valid_to_ns",
        "source",
    ),
    "EventRow": (
        "stamp_ns",
        "agent_id",
        "kind",
        "subject_id",
        "subject_owner_id",
        "property",
        "sub_property",
        "target_id",
        "target_owner_id",
        "value_text",
        "previous_text",
        "confidence",
        "source",
    ),
}
#: Key columns a terminal table leaves out when they are empty in every row.
OPTIONAL_KEYS = frozenset({"subject_owner_id", "sub_property", "target_owner_id"})
_HEADERS = {
    "subject_id": "subject",
    "target_id": "target",
    "value_text": "value",
    "value_num": "num",
    "valid_from_ns": "from",
    "valid_to_ns": "to",
    "stamp_ns": "time",
    "agent_id": "agent",
    "previous_text": "previous",
    "entity_id": "entity",
    "subject_owner_id": "subject_owner",
    "target_owner_id": "target_owner",
}


def listing_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--limit N``, ``--json`` and ``--csv`` (keyword arguments ``limit`` and ``fmt``) to
    a command that lists rows; print them with :func:`emit` (or :class:`RowWriter`)."""
    func = click.option(
        "--csv", "fmt", flag_value="csv", help="Comma-separated values, every field (times in ns)."
    )(func)
    func = click.option(
        "--json", "fmt", flag_value="json", help="JSON lines, one object per row (times in ns)."
    )(func)
    return click.option(
        "--limit", type=_RowCount(0, 2**63 - 1), metavar="N", help="At most N rows."
    )(func)


class _RowCount(click.IntRange):
    """0 to 2^63 - 1 (a usage error outside), shown as ``x>=0``."""

    def _describe_range(self) -> str:
        return "x>=0"


def mode(fmt: str | None) -> str:
    """``json``, ``csv``, ``table`` (stdout is a terminal) or ``tsv`` (it is not)."""
    return fmt or ("table" if sys.stdout.isatty() else "tsv")


def emit(
    rows: Sequence[Any],
    fmt: str | None,
    *,
    columns: Sequence[str] | None = None,
    title: str | None = None,
    empty: str = "(no rows)",
    limit: int | None = None,
    frame: TimeFrame | None = None,
) -> None:
    """Print rows (NamedTuples, or tuples with ``columns``): at most ``limit``, as ``fmt``
    says (see :func:`mode`); ``empty`` is said when there is none (on stderr when piped).

    Tables show ``*_ns`` times through ``frame`` (default: the command's,
    :func:`toaster.cli.checks.command_frame`): elapsed or dates as ``--time`` says; JSON
    and CSV keep integer ns.
    """
    rows = rows[:limit] if limit is not None else rows
    if columns is None:
        columns = list(rows[0]._fields) if rows else []
    how = mode(fmt)
    listing = Listing(
        type(rows[0]).__name__ if rows else "",
        list(columns),
        [tuple(r) for r in rows],
        title,
        empty,
        frame,
    )
    _WRITERS[how](listing)


class Listing(NamedTuple):
    """Rows to print: their type's name, columns, values, title, what to say when empty."""

    kind: str
    columns: list[str]
    records: list[tuple[Any, ...]]
    title: str | None
    empty: str
    frame: TimeFrame | None

    def cells(self, *, terminal: bool) -> tuple[list[str], list[list[str]]]:
        """The table's headers and text cells (times through the frame)."""
        shown = shown_columns(self.kind, self.columns, self.records, terminal=terminal)
        index = [self.columns.index(name) for name in shown]
        frame = self.frame if self.frame is not None else _frame_for(shown)
        cell = _cell if terminal else _tsv_cell
        cells = [
            [cell(name, record[i], frame) for name, i in zip(shown, index, strict=True)]
            for record in self.records
        ]
        return [_HEADERS.get(name, name) for name in shown], cells


def _json(out: Listing) -> None:
    for record in out.records:
        obj = dict(zip(out.columns, record, strict=True))
        click.echo(json_line(obj if out.title is None else {"table": out.title, **obj}))


def _csv(out: Listing) -> None:
    if out.title is not None:
        click.echo(f"# {visible(out.title)}")
    for line in (out.columns, *out.records):
        _write(csv_line(line))


def _write(line: str) -> None:
    """One line of data on stdout as it is (``click.echo`` would strip escape sequences)."""
    sys.stdout.write(line + "\n")


def _tsv(out: Listing) -> None:
    if not out.records:
        click.echo(out.empty, err=True)
        return
    headers, cells = out.cells(terminal=False)
    if out.title is not None:
        click.echo(f"# {visible(out.title)}")
    for line in (headers, *cells):
        click.echo("\t".join(visible(cell) for cell in line))


def _table(out: Listing) -> None:
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    if not out.records:
        click.echo(out.empty)
        return
    headers, cells = out.cells(terminal=True)
    table = Table(title=None if out.title is None else Text(visible(out.title)), show_lines=False)
    for header in headers:
        table.add_column(header, overflow="fold")
    for line in cells:
        table.add_row(*(Text(visible(cell)) for cell in line))  # Text: no markup
    Console(highlight=False).print(table)


#: output mode (:func:`mode`) -> how rows are printed
_WRITERS: dict[str, Callable[[Listing], None]] = {
    "json": _json,
    "csv": _csv,
    "tsv": _tsv,
    "table": _table,
}


def shown_columns(
    kind: str, columns: Sequence[str], records: Sequence[tuple[Any, ...]], *, terminal: bool
) -> list[str]:
    """The columns a table of ``kind`` rows shows (:data:`TABLE_COLUMNS`, else all); on a
    terminal, optional key columns empty in every row are left out."""
    shown = [c for c in TABLE_COLUMNS.get(kind, columns) if c in columns]
    if terminal:
        shown = [
            c
            for c in shown
            if c not in OPTIONAL_KEYS
            or any(record[columns.index(c)] not in (None, "") for record in records)
        ]
    return shown


def _frame_for(shown: Sequence[str]) -> TimeFrame | None:
    if not any(name.endswith("_ns") for name in shown):
        return None
    from toaster.cli.checks import command_frame

    return command_frame()


def _cell(name: str, value: Any, frame: TimeFrame | None) -> str:
    if value is None:
        return "(current)" if name == "valid_to_ns" else ""
    if name.endswith("_ns") and isinstance(value, int):
        return frame.show(value) if frame is not None else format_ns(value)
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _tsv_cell(name: str, value: Any, frame: TimeFrame | None) -> str:
    """A tab-separated cell: text as :func:`~toaster.quoting.csv_text` (a spreadsheet opening
    it reads no formula), the rest as in a table."""
    return csv_text(value) if isinstance(value, str) else _cell(name, value, frame)


class RowWriter:
    """Rows printed as they come (``watch``), in the same formats as :func:`emit`; on a
    terminal each row is ``line(row)``."""

    def __init__(self, fmt: str | None, columns: Sequence[str], line: Callable[[Any], str]) -> None:
        self.how = mode(fmt)
        self.columns = list(columns)
        self.line = line
        self._started = False

    def write(self, row: Any, frame: TimeFrame | None = None) -> None:
        """Print one row (a NamedTuple with :attr:`columns`) now."""
        record = tuple(row)
        if self.how == "json":
            click.echo(json_line(dict(zip(self.columns, record, strict=True))))
        elif self.how == "table":
            click.echo(visible(self.line(row)))
        else:
            kind = type(row).__name__
            shown = shown_columns(kind, self.columns, [record], terminal=False)
            if not self._started:
                header = (
                    self.columns
                    if self.how == "csv"
                    else [_HEADERS.get(name, name) for name in shown]
                )
                self._emit(header)
            if self.how == "csv":
                self._emit(record)
            else:
                self._emit(
                    [_tsv_cell(name, record[self.columns.index(name)], frame) for name in shown]
                )
        self._started = True
        sys.stdout.flush()

    def _emit(self, values: Sequence[Any]) -> None:
        if self.how == "csv":
            _write(csv_line(values))
        else:
            click.echo("\t".join(visible(str(v)) for v in values))


def emit_rows(
    rows: Iterable[tuple[Any, ...]],
    fmt: str | None,
    *,
    columns: Sequence[str],
    frame: TimeFrame | None = None,
) -> None:
    """Print tuples under ``columns`` as :func:`emit` does, each as it comes when piped
    (JSON, CSV, tab-separated lines, by :class:`RowWriter`: one row is held at a time); a
    terminal table needs them all (it sizes its columns to them). Blobs are shown in hex as
    PostgreSQL prints them (``\\x0a1b``). ``*_ns`` times are shown through ``frame`` (look it
    up before a transaction that yields the rows is opened)."""
    records = (tuple("\\x" + v.hex() if isinstance(v, bytes) else v for v in row) for row in rows)
    if mode(fmt) == "table":
        emit(list(records), fmt, columns=columns, frame=frame)
        return
    writer = RowWriter(fmt, columns, str)
    written = 0
    for written, record in enumerate(records, 1):  # noqa: B007 (written is read after it)
        writer.write(record, frame)
    if not written:  # what emit prints for no rows: CSV's header, or a note on stderr
        emit([], fmt, columns=columns, frame=frame)


def say(message: str) -> None:
    """A status line for people (stderr, so that stdout stays clean for data)."""
    click.echo(message, err=True)
