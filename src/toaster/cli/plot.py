"""``toaster plot-facts``: the timeline of facts per agent as PNG, SVG, PDF, gnuplot .dat or CSV."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import click

from toaster.outputs.plotting.select import MAX_FACTS


def window_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """``--from``/``--to`` (aliases ``--since``/``--until``), parsed with toaster's time rules."""
    func = click.option(
        "--to", "--until", "until", metavar="TIME", help="Window end (ns, ISO date, 'now')."
    )(func)
    return click.option(
        "--from", "--since", "since", metavar="TIME", help="Window start (ns, ISO date, 'now')."
    )(func)


def parse_window(since: str | None, until: str | None) -> tuple[int | None, int | None]:
    """The window in ns (None stays None)."""
    from toaster.cli.checks import parse_time_option

    return parse_time_option(since, "--from"), parse_time_option(until, "--to")


def _many(values: tuple[str, ...]) -> list[str] | None:
    return list(values) or None


@click.command("plot-facts")
@click.argument("output", type=click.Path(dir_okay=False, writable=True))
@click.option("--subject", "-s", multiple=True, help="Subject id (repeat for several).")
@click.option("--property", "-p", "prop", multiple=True, help="Property, e.g. IsOn (repeatable).")
@click.option("--target", "-t", multiple=True, help="Target id (repeatable).")
@click.option(
    "--agent",
    "-a",
    multiple=True,
    help="Agent whose beliefs to show (repeatable; default: every agent).",
)
@click.option("--reference", help="Agent the others are compared with (default: the robot).")
@window_options
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["png", "svg", "pdf", "dat", "csv"]),
    help="Output format (default: from OUTPUT's suffix).",
)
@click.option("--title", help="Title of the picture.")
@click.option(
    "--numbers",
    type=click.Choice(["both", "only", "off"]),
    default="both",
    show_default=True,
    help="Facts with a number (Distance, IsMoving speed, angles): also draw the "
    "number over time (both), only the numbers (only), or the bars only (off).",
)
@click.option(
    "--max-facts",
    "--max-rows",
    "max_facts",
    type=click.IntRange(min=0),
    default=MAX_FACTS,
    show_default=True,
    metavar="N",
    help="Draw at most N facts, the most relevant (false beliefs, then the "
    "reference agent's, then those that change most); 0 = every fact.",
)
@click.pass_obj
def plot_facts(
    app: Any,
    output: str,
    subject: tuple[str, ...],
    prop: tuple[str, ...],
    target: tuple[str, ...],
    agent: tuple[str, ...],
    reference: str | None,
    since: str | None,
    until: str | None,
    fmt: str | None,
    title: str | None,
    numbers: str,
    max_facts: int,
) -> None:
    """Draw the timeline of facts to OUTPUT (.png, .svg, .pdf, .dat for gnuplot, .csv).

    One row per agent and fact: value changes, confidence, and where an agent's belief
    differs from the reference agent's (false beliefs are hatched in red). Facts that carry
    a number (value_num) get a second panel: the number over time, one step line per agent,
    gaps where the fact does not hold (--numbers). At most --max-facts facts are drawn, the
    most relevant; stderr says how many were left out. Pictures need matplotlib
    (pip install 'toaster[plot]').
    """
    from functools import partial

    from toaster.cli.checks import command_frame
    from toaster.outputs.plotting import plot_facts as plot
    from toaster.quoting import shell_word, visible

    db = app.db
    lo, hi = parse_window(since, until)
    result = _with_progress(
        partial(
            plot,
            db,
            output,
            subject=_many(subject),
            property=_many(prop),
            target=_many(target),
            agents=_many(agent),
            since=lo,
            until=hi,
            reference=reference,
            format=fmt,
            title=title,
            numbers=numbers,
            max_facts=max_facts,
            frame=command_frame(),
        )
    )
    timeline = result.timeline
    false = sum(d.kind == "false_belief" for d in timeline.divergences)
    with_numbers = len(timeline.number_lanes) if numbers != "off" else 0
    facts = with_numbers if numbers == "only" else len(timeline.lanes)
    click.echo(
        f"wrote {result.path} ({facts} facts, {with_numbers} with numbers, "
        f"{len(timeline.agents)} agents, {false} false-belief spans)"
    )
    if result.companion is not None:
        click.echo(f"draw it with: gnuplot -p {shell_word(str(result.companion))}")
    if result.left_out:
        click.echo(
            f"plot-facts: drew the {facts} most relevant facts; {result.left_out} more "
            "matched and were left out (false beliefs come first, then facts "
            f"{visible(timeline.reference)} holds, then those that change most). Choose "
            "with --subject, --property, --target, --agent or --from/--to, or draw more "
            "with --max-facts N (0 = all).",
            err=True,
        )


def _with_progress(plot: Callable[..., Any]) -> Any:
    """``plot(progress=...)`` with a rich progress bar on stderr when it is a terminal."""
    if not sys.stderr.isatty():
        return plot()
    from rich.console import Console
    from rich.progress import Progress

    with Progress(console=Console(stderr=True), transient=True) as bar:
        tasks: dict[str, Any] = {}

        def report(step: str, done: int, total: int | None) -> None:
            if step not in tasks:  # a new step: its own bar (pulsing when total is None)
                for old in tasks.values():
                    bar.remove_task(old)
                tasks.clear()
                tasks[step] = bar.add_task(step, total=total)
            bar.update(tasks[step], completed=done)

        return plot(progress=report)
