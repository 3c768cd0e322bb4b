"""``toaster execute``: raw SQL (read-only unless --write), ARE_IN_TABLE, EMPTY, PRINT."""

from __future__ import annotations

from typing import Any

import click

from toaster.cli.info import _self_agent, fact_options
from toaster.cli.output import emit, output_options, say
from toaster.db import readonly

COMMANDS = ("SQL", "ARE_IN_TABLE", "EMPTY", "PRINT")


@click.command()
@click.argument("command", type=click.Choice(COMMANDS, case_sensitive=False))
@click.argument("argument", required=False)
@click.option("--write", is_flag=True,
              help="SQL: run any SQL (several statements, writes, settings) as the "
                   "connecting role, without the read-only bounds.")
@click.option("--param", "params", multiple=True, metavar="NAME=VALUE",
              help="SQL: a bound parameter for :NAME (repeatable).")
@click.option("--max-rows", type=click.IntRange(1, 2**31 - 2),
              default=readonly.DEFAULT_MAX_ROWS, show_default=True,
              help="SQL, read-only: show at most this many rows (a note says when more).")
@click.option("--max-bytes", type=click.IntRange(1024), default=readonly.DEFAULT_MAX_BYTES,
              show_default=True, help="SQL, read-only: fail past this many bytes of values.")
@click.option("--timeout", "timeout_s", type=click.FloatRange(0, 1e6, min_open=True),
              default=readonly.DEFAULT_TIMEOUT_S, show_default=True, metavar="SECONDS",
              help="SQL, read-only: fail past this many seconds.")
@fact_options
@click.option("--yes", is_flag=True, help="EMPTY: do not ask for confirmation.")
@output_options
@click.pass_obj
def execute(app: Any, command: str, argument: str | None, write: bool, params: tuple[str, ...],
            max_rows: int, max_bytes: int, timeout_s: float, yes: bool, fmt: str | None,
            **opts: Any) -> None:
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
    from toaster import queries as q

    db = app.db
    command = command.upper()
    if command == "SQL":
        if not argument:
            raise click.UsageError(
                'execute SQL needs the statement: toaster execute SQL "SELECT 1"')
        bad = next((p for p in params if "=" not in p), None)
        if bad is not None:
            raise click.UsageError(f"--param {bad!r} takes NAME=VALUE, e.g. --param {bad}=1")
        bound = dict(p.split("=", 1) for p in params) if params else None
        result = q.execute(db, argument, bound, write=write, max_rows=max_rows,
                           max_bytes=max_bytes, timeout_s=timeout_s)
        if result.columns:
            emit(result.rows, fmt, columns=result.columns)
            if result.truncated:
                say(f"note: only the first {max_rows} rows are shown: add a LIMIT, or raise "
                    "--max-rows")
        else:
            say(f"ok ({result.rowcount} row(s) affected)")
    elif command == "ARE_IN_TABLE":
        from toaster.model import Fact

        agent = _self_agent(db, opts["agent"])
        db.store().check_agent(agent)
        if not (opts["subject"] and opts["property"]):
            raise click.UsageError("ARE_IN_TABLE needs --subject and --property")
        fact = Fact(opts["subject"], opts["property"], opts["target"] or "",
                    sub_property=opts["sub_property"] or "")
        answer = q.are_in_table(db, agent, [fact])[0]
        click.echo("true" if answer else "false")
        if not answer:
            raise SystemExit(1)
    elif command == "EMPTY":
        scope = (argument or "").upper()
        if scope not in ("ALL", "AGENT"):
            raise click.UsageError("execute EMPTY needs ALL or AGENT --agent A")
        emptied: str | None = opts["agent"] if scope == "AGENT" else None
        if scope == "AGENT" and not emptied:
            raise click.UsageError("execute EMPTY AGENT needs --agent")
        what = f"agent {emptied!r}" if emptied else "every agent"
        if not yes:
            click.confirm(f"delete the facts, memory and events of {what}?", abort=True)
        db.store().empty(emptied)
        say(f"emptied {what}")
    else:
        scope = (argument or "ALL").upper()
        agents = [a.id for a in q.agents(db)]
        if scope == "AGENT":
            agents = [_self_agent(db, opts["agent"])]
            db.store().check_agent(agents[0])
        for agent in agents:
            emit(q.current_facts(db, agent), fmt, title=f"fact_table_{agent}")
            if scope == "ALL":
                emit(q.memory(db, agent), fmt, title=f"memory_table_{agent}")
        if scope == "ALL":
            emit(q.entities(db), fmt, title="entities")
            emit(q.events(db), fmt, title="events")
