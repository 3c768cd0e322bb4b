"""plot_facts: the timeline of facts per agent, as a picture (PNG, SVG, PDF) or data (.dat, CSV).

>>> import toaster
>>> from toaster.outputs.plotting import plot_facts                            # doctest: +SKIP
>>> db = toaster.connect("sqlite:///run.db")                           # doctest: +SKIP
>>> plot_facts(db, "mug.png", subject="mug", property="IsOn")         # doctest: +SKIP
>>> plot_facts(db, "dist.svg", property="Distance", numbers="only")    # doctest: +SKIP

Facts that carry numbers (``value_num``: Distance, IsMoving speeds, angles) are also drawn as
step lines of their number over time, refreshes included (``numbers``: ``both``, ``only``,
``off``). Pictures need the ``plot`` extra (matplotlib); data files need nothing beyond toaster.
At most :data:`MAX_FACTS` facts are drawn, the most relevant (``max_facts``;
:mod:`toaster.outputs.plotting.select`), so that a plot stays readable at any database size.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from toaster.errors import InvalidInputError
from toaster.outputs.plotting.datafiles import CSV_COLUMNS, gnuplot_script, write_csv, write_dat
from toaster.outputs.plotting.select import (
    MAX_FACTS,
    Selection,
    check_max_facts,
    ranked,
    select_facts,
)
from toaster.outputs.plotting.timeline import (
    FALSE_BELIEF,
    NUMBERS,
    UNAWARE,
    UNITS,
    Change,
    Divergence,
    Lane,
    Point,
    Series,
    Signal,
    Timeline,
    add_signals,
    build_timeline,
    check_numbers,
    fact_label,
    number_unit,
    panels,
    signal_points,
    timeline_from_rows,
)

if TYPE_CHECKING:
    from toaster.db.database import Database
    from toaster.timeutil import TimeFrame

IMAGE_FORMATS = ("png", "svg", "pdf")
FORMATS = (*IMAGE_FORMATS, "dat", "csv")

#: ``progress(step, done, total)``: what plot_facts is doing (total None: unknown).
Progress = Callable[[str, int, int | None], None]


class PlotResult(NamedTuple):
    """What :func:`plot_facts` wrote: the output file, any companion file, the data drawn
    (the facts kept), for a picture the matplotlib ``Figure`` that was saved, and how many
    matching facts were left out (see :data:`MAX_FACTS`)."""

    path: Path
    companion: Path | None  # the gnuplot script beside a .dat
    timeline: Timeline
    figure: Any = None
    left_out: int = 0


def output_format(path: str | Path, format: str | None = None) -> str:
    """The format named (or implied by the file suffix); an unknown one raises a one-line error."""
    name = (format or Path(path).suffix.lstrip(".")).lower()
    if name not in FORMATS:
        shown = f"format {format!r}" if format else f"file suffix of {str(path)!r}"
        msg = f"unknown plot {shown}: use one of {', '.join(FORMATS)}"
        raise InvalidInputError(msg)
    return name


def plot_facts(
    db: Database,
    output: str | Path,
    *,
    subject: str | Sequence[str] | None = None,
    property: str | Sequence[str] | None = None,
    target: str | Sequence[str] | None = None,
    agents: str | Sequence[str] | None = None,
    since: int | None = None,
    until: int | None = None,
    reference: str | None = None,
    format: str | None = None,
    title: str | None = None,
    dpi: int = 120,
    numbers: str = "both",
    frame: TimeFrame | None = None,
    max_facts: int | None = MAX_FACTS,
    progress: Progress | None = None,
) -> PlotResult:
    """Write the timeline of the matching facts to ``output``.

    Args:
        db: an open :class:`toaster.Database`.
        output: file to write; its suffix picks the format unless ``format`` is given.
        subject, property, target: filters (a list matches any of its items).
        agents: whose beliefs to show (default: every agent).
        since, until: the window in ns (default: the span of the matching intervals).
        reference: the agent others are compared with (default: the robot, ``is_self``).
        format: ``png``, ``svg``, ``pdf`` (matplotlib), ``dat`` (gnuplot, with a ``.gp``
            script beside it) or ``csv``.
        numbers: for facts that carry numbers (``value_num``), ``both`` (default: the bars,
            plus a panel with the number over time; number blocks in a ``.dat``, number rows
            in a CSV), ``only`` (the numbers only; facts without numbers are left out) or
            ``off`` (the bars only).
        frame: the time axis (default ``db.time_frame()``: seconds since the data's start,
            dates for real data; ``db.time_frame("elapsed")`` or ``"date"`` to choose).
        max_facts: draw (or write) at most this many facts, the most relevant ones
            (:mod:`toaster.outputs.plotting.select`); ``PlotResult.left_out`` says how many matched
            beyond; 0 or None: every matching fact.
        progress: called as ``progress(step, done, total)`` while it works (steps: reading,
            drawing with one call per panel, saving).
    """
    report: Progress = progress or (lambda _step, _done, _total: None)
    fmt = output_format(output, format)
    check_numbers(numbers)
    check_max_facts(max_facts)
    if fmt in IMAGE_FORMATS:
        from toaster.outputs.plotting.render import _matplotlib

        _matplotlib()  # fail on a missing extra before reading the database
    report("reading facts", 0, None)
    timeline = build_timeline(
        db,
        subject=subject,
        property=property,
        target=target,
        agents=agents,
        since=since,
        until=until,
        reference=reference,
        numbers=numbers != "off",
        frame=frame,
    )
    panels(timeline, numbers)  # "only" with no number: one-line error before writing
    chosen = select_facts(timeline, max_facts, numbers_only=numbers == "only")
    timeline, left_out = chosen.timeline, chosen.left_out
    path = Path(output)
    if fmt == "dat":
        report("writing", 0, None)
        return PlotResult(path, write_dat(timeline, path, numbers), timeline, None, left_out)
    if fmt == "csv":
        report("writing", 0, None)
        return PlotResult(write_csv(timeline, path, numbers), None, timeline, None, left_out)
    from toaster.outputs.plotting.render import render, text_settings

    figure = render(
        timeline,
        title=title,
        numbers=numbers,
        on_panel=lambda done, total: report("drawing", done, total),
    )
    report("saving", 0, None)
    with text_settings():  # tick labels are made while saving
        figure.savefig(path, format=fmt, dpi=dpi)
    return PlotResult(path, None, timeline, figure, left_out)


__all__ = [
    "CSV_COLUMNS",
    "FALSE_BELIEF",
    "FORMATS",
    "IMAGE_FORMATS",
    "MAX_FACTS",
    "NUMBERS",
    "UNAWARE",
    "UNITS",
    "Change",
    "Divergence",
    "Lane",
    "PlotResult",
    "Point",
    "Progress",
    "Selection",
    "Series",
    "Signal",
    "Timeline",
    "add_signals",
    "build_timeline",
    "check_max_facts",
    "check_numbers",
    "fact_label",
    "gnuplot_script",
    "number_unit",
    "output_format",
    "panels",
    "plot_facts",
    "ranked",
    "select_facts",
    "signal_points",
    "timeline_from_rows",
    "write_csv",
    "write_dat",
]
