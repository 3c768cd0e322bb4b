"""``toaster execute``: raw SQL (read-only unless --write), ARE_IN_TABLE, EMPTY, PRINT."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import click

from toaster.cli.info import _self_agent, fact_options
from toaster.cli.output import emit, emit_rows, listing_options, mode, say
from toaster.db import readonly

if TYPE_CHECKING:
    from toaster.db.database import Database

NAMES = ("SQL", "ARE_IN_TABLE", "EMPTY", "PRINT")


@click.command()
@click.argument("command", type=click.Choice(NAMES, case_sensitive=False))
@click.argument("argument", required=False)
@click.option(
    "--write",
    is_flag=True,
    help="SQL: run any SQL (several statements, writes, settings) as the "
    "connecting role, without the read-only bounds.",
)
@click.option(
    "--param",
    "params",
    multiple=True,
    metavar="NAME=VALUE",
    help="SQL: a bound parameter for :NAME (repeatable).",
)
@click.option(
    "--max-rows",
    type=click.IntRange(1, 2**31 - 2),
    default=readonly.DEFAULT_MAX_ROWS,
    show_default=True,
    help="SQL, read-only: show at most this many rows (a note says when more).",
)
@click.option(
    "--max-bytes",
    type=click.IntRange(1024),
    default=readonly.DEFAULT_MAX_BYTES,
    show_default=True,
    help="SQL, read-only: fail past this many bytes of values.",
)
@click.option(
    "--timeout",
    "timeout_s",
    type=click.FloatRange(0, 1e6, min_open=True),
    default=readonly.DEFAULT_TIMEOUT_S,
    show_default=True,
    metavar="SECONDS",
    help="SQL, read-only: fail past this many seconds.",
)
@fact_options
@click.option("--yes", is_flag=True, help="EMPTY: do not ask for confirmation.")
@listing_options
@click.pass_obj
def execute(
    app: Any, command: str, argument: str | None, fmt: str | None, limit: int | None, **opts: Any
) -> None:
    """Run SQL or one of the original's maintenance commands.

    \b
    SQL "STATEMENT" [--param k=v] [--write]   one read-only statement unless --write:
        SELECT, WITH, VALUES, TABLE, EXPLAIN, SHOW (PRAGMA reads on SQLite) that cannot
        write, end its transaction, change settings or roles, or act on the server;
        bounded by --max-rows, --max-bytes, --timeout (docs/execute.md)
    ARE_IN_TABLE --agent A --subject S --property P [--target T]   true/false
    EMPTY ALL | EMPTY AGENT --agent A          delete facts, memory and events
    PRINT ALL | PRINT AGENT --agent A          print the tables
    """
    COMMANDS[command.upper()](Call(app.db, argument, fmt, limit, opts))


@dataclass(frozen=True)
class Call:
    """One execute call: the database, its ARGUMENT, the output choice and the options."""

    db: Database
    argument: str | None
    fmt: str | None
    limit: int | None
    opts: dict[str, Any]


def _sql(call: Call) -> None:
    from toaster import queries as q
    from toaster.cli.checks import command_frame

    opts = call.opts
    if not call.argument:
        raise click.UsageError('execute SQL needs the statement: toaster execute SQL "SELECT 1"')
    bad = next((p for p in opts["params"] if "=" not in p), None)
    if bad is not None:
        raise click.UsageError(f"--param {bad!r} takes NAME=VALUE, e.g. --param {bad}=1")
    bound = dict(p.split("=", 1) for p in opts["params"]) or None
    # Times are shown through the data's frame, looked up outside the statement's transaction.
    shows_times = mode(call.fmt) in ("tsv", "table")
    if opts["write"]:
        result = q.execute(call.db, call.argument, bound, write=True)
        if not result.columns:
            say(f"ok ({result.rowcount} row(s) affected)")
            return
        emit_rows(
            itertools.islice(result.rows, call.limit),
            call.fmt,
            columns=result.columns,
            frame=command_frame() if shows_times else None,
        )
        return
    max_rows = opts["max_rows"] if call.limit is None else max(1, min(opts["max_rows"], call.limit))
    frame = command_frame() if shows_times else None
    with q.execute_stream(
        call.db,
        call.argument,
        bound,
        max_rows=max_rows,
        max_bytes=opts["max_bytes"],
        timeout_s=opts["timeout_s"],
    ) as rows:
        if not rows.columns:
            say("ok (0 row(s) affected)")
            return
        emit_rows(itertools.islice(rows, call.limit), call.fmt, columns=rows.columns, frame=frame)
    if rows.truncated and (call.limit is None or call.limit > max_rows):
        say(f"note: only the first {max_rows} rows are shown: add a LIMIT, or raise --max-rows")


def _are_in_table(call: Call) -> None:
    from toaster import queries as q
    from toaster.model import Fact

    opts = call.opts
    agent = _self_agent(call.db, opts["agent"])
    call.db.store().check_agent(agent)
    if not (opts["subject"] and opts["property"]):
        raise click.UsageError("ARE_IN_TABLE needs --subject and --property")
    fact = Fact(
        opts["subject"],
        opts["property"],
        opts["target"] or "",
        sub_property=opts["sub_property"] or "",
    )
    answer = q.are_in_table(call.db, agent, [fact])[0]
    click.echo("true" if answer else "false")
    if not answer:
        raise SystemExit(1)


def _empty(call: Call) -> None:
    scope = (call.argument or "").upper()
    if scope not in ("ALL", "AGENT"):
        raise click.UsageError("execute EMPTY needs ALL or AGENT --agent A")
    emptied: str | None = call.opts["agent"] if scope == "AGENT" else None
    if scope == "AGENT" and not emptied:
        raise click.UsageError("execute EMPTY AGENT needs --agent")
    what = f"agent {emptied!r}" if emptied else "every agent"
    if not call.opts["yes"]:
        click.confirm(f"delete the facts, memory and events of {what}?", abort=True)
    call.db.store().empty(emptied)
    say(f"emptied {what}")


def _print(call: Call) -> None:
    from toaster import queries as q

    db, scope = call.db, (call.argument or "ALL").upper()
    if scope not in ("ALL", "AGENT"):
        raise click.UsageError("execute PRINT takes ALL or AGENT --agent A")
    if scope == "AGENT":
        agents = [_self_agent(db, call.opts["agent"])]
        db.store().check_agent(agents[0])
    else:
        agents = [a.id for a in q.agents(db)]
    tables: list[tuple[str, Any]] = []
    for agent in agents:
        tables.append((f"fact_table_{agent}", q.current_facts(db, agent, limit=call.limit)))
        if scope == "ALL":
            tables.append((f"memory_table_{agent}", q.memory(db, agent, limit=call.limit)))
    if scope == "ALL":
        tables += [("entities", q.entities(db)), ("events", q.events(db, limit=call.limit))]
    for title, rows in tables:
        emit(rows, call.fmt, title=title, limit=call.limit)


#: execute COMMAND -> what runs it
COMMANDS: dict[str, Callable[[Call], None]] = {
    "SQL": _sql,
    "ARE_IN_TABLE": _are_in_table,
    "EMPTY": _empty,
    "PRINT": _print,
}
