"""``toaster plot-facts``: the timeline of facts per agent as PNG, SVG, PDF, gnuplot .dat or CSV."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import click

DEFAULT_DB = "sqlite:///toaster.db"


def db_option(func: Callable[..., Any]) -> Callable[..., Any]:
    """``--db URL`` (env TOASTER_DB); without it the main group's database is used."""
    return click.option("--db", "url", envvar="TOASTER_DB", metavar="URL",
                        help="sqlite:///FILE.db or postgresql://HOST/DB (env TOASTER_DB; "
                             f"default {DEFAULT_DB}).")(func)


def window_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """``--from``/``--to`` (aliases ``--since``/``--until``), parsed with toaster's time rules."""
    func = click.option("--to", "--until", "until", metavar="TIME",
                        help="Window end (ns, ISO date, 'now').")(func)
    return click.option("--from", "--since", "since", metavar="TIME",
                        help="Window start (ns, ISO date, 'now').")(func)


def parse_window(since: str | None, until: str | None) -> tuple[int | None, int | None]:
    """The window in ns (None stays None)."""
    from toaster.cli.checks import parse_time_option

    return parse_time_option(since, "--from"), parse_time_option(until, "--to")


@contextmanager
def open_db(url: str | None) -> Iterator[Any]:
    """The database named by ``--db``, else the group's (``ctx.obj.db``), else the default;
    toaster's expected errors become one-line messages."""
    from toaster.errors import ToasterError

    ctx = click.get_current_context()
    own = url is not None or not hasattr(ctx.obj, "db")
    try:
        if own:
            import toaster

            db = toaster.connect(url or DEFAULT_DB)
        else:
            db = ctx.obj.db
        try:
            yield db
        finally:
            if own:
                db.close()
    except ToasterError as exc:
        raise click.ClickException(str(exc)) from None


def _many(values: tuple[str, ...]) -> list[str] | None:
    return list(values) or None


@click.command("plot-facts")
@click.argument("output", type=click.Path(dir_okay=False, writable=True))
@click.option("--subject", "-s", multiple=True, help="Subject id (repeat for several).")
@click.option("--property", "-p", "prop", multiple=True, help="Property, e.g. IsOn (repeatable).")
@click.option("--target", "-t", multiple=True, help="Target id (repeatable).")
@click.option("--agent", "-a", multiple=True,
              help="Agent whose beliefs to show (repeatable; default: every agent).")
@click.option("--reference", help="Agent the others are compared with (default: the robot).")
@window_options
@click.option("--format", "fmt", type=click.Choice(["png", "svg", "pdf", "dat", "csv"]),
              help="Output format (default: from OUTPUT's suffix).")
@click.option("--title", help="Title of the picture.")
@click.option("--numbers", type=click.Choice(["both", "only", "off"]), default="both",
              show_default=True,
              help="Facts with a number (Distance, IsMoving speed, angles): also draw the "
                   "number over time (both), only the numbers (only), or the bars only (off).")
@db_option
def plot_facts(output: str, subject: tuple[str, ...], prop: tuple[str, ...],
               target: tuple[str, ...], agent: tuple[str, ...], reference: str | None,
               since: str | None, until: str | None, fmt: str | None, title: str | None,
               numbers: str, url: str | None) -> None:
    """Draw the timeline of facts to OUTPUT (.png, .svg, .pdf, .dat for gnuplot, .csv).

    One row per agent and fact: value changes, confidence, and where an agent's belief
    differs from the reference agent's (false beliefs are hatched in red). Facts that carry
    a number (value_num) get a second panel: the number over time, one step line per agent,
    gaps where the fact does not hold (--numbers). Pictures need matplotlib
    (pip install 'toaster[plot]').
    """
    from toaster.plotting import plot_facts as plot

    with open_db(url) as db:
        lo, hi = parse_window(since, until)
        result = plot(db, output, subject=_many(subject), property=_many(prop),
                      target=_many(target), agents=_many(agent), since=lo, until=hi,
                      reference=reference, format=fmt, title=title, numbers=numbers)
    timeline = result.timeline
    false = sum(d.kind == "false_belief" for d in timeline.divergences)
    with_numbers = len(timeline.number_lanes) if numbers != "off" else 0
    facts = with_numbers if numbers == "only" else len(timeline.lanes)
    click.echo(f"wrote {result.path} ({facts} facts, {with_numbers} with numbers, "
               f"{len(timeline.agents)} agents, {false} false-belief spans)")
    if result.companion is not None:
        click.echo(f"draw it with: gnuplot -p {result.companion}")
