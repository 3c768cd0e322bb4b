"""Drawing a :class:`~toaster.outputs.plotting.timeline.Timeline` with matplotlib (the ``plot``
extra).

One panel per fact, one row per agent. A bar is a held value (its colour is the value, its
opacity and the thin black line inside it the confidence); red hatching marks a false belief
(the agent holds a value the reference agent does not), grey dots a fact the agent is unaware
of. Below the bars of a fact that carries numbers, a second panel draws its number over time
(one step line per agent, gaps where the fact does not hold; y axis: the property and its
unit). matplotlib is imported here only, and only through :class:`matplotlib.figure.Figure`,
so no GUI backend and no global pyplot state are involved.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from toaster.extras import require
from toaster.outputs.plotting.timeline import FALSE_BELIEF, Lane, Timeline, legend_notes, panels
from toaster.quoting import mpl_text, visible
from toaster.timeutil import NS_PER_S

BAR = 0.6
NUMBER_PANEL_HEIGHT = 1.7  # inches
_MIN_LABEL_FRACTION = 0.06


def _matplotlib() -> Any:
    require("plot", "plot-facts")
    from matplotlib.figure import Figure

    return Figure


def text_settings() -> Any:
    """The settings under which ids show as they are (:func:`toaster.quoting.mpl_text`): no
    LaTeX, ``$`` escapes read (a user's matplotlibrc may say otherwise); draw and save in it."""
    import matplotlib as mpl

    return mpl.rc_context({"text.usetex": False, "text.parse_math": True})


def number_gid(lane: Lane, agent: str) -> str:
    """The ``gid`` of the number line of ``agent`` in ``lane`` (an ``id`` in an SVG; ids
    :func:`~toaster.quoting.visible`, XML holds no control character)."""
    return f"numbers: {visible(lane.label)} | {visible(agent)}"


def render(
    timeline: Timeline,
    *,
    title: str | None = None,
    numbers: str = "both",
    on_panel: Callable[[int, int], None] | None = None,
) -> Any:
    """A matplotlib ``Figure`` of the timeline (save it with ``fig.savefig(path)``).

    ``numbers``: ``both`` (bars, and a number panel under each fact that carries numbers),
    ``only`` (the number panels only) or ``off`` (the bars only). A number line is a
    ``Line2D`` whose ``gid`` is :func:`number_gid` and whose data are seconds since the data's
    start (:attr:`Timeline.axis`) and the numbers (NaN: the fact does not hold).
    ``on_panel(done, total)`` is called after each panel is drawn. The legend says what the
    hatching and dots mean and what each nested holder ``A>B`` plotted is
    (:func:`~toaster.outputs.plotting.timeline.legend_notes`). Ids and values show as they are
    (:func:`~toaster.quoting.mpl_text`); ``title`` is matplotlib text (``$...$`` is math).
    """
    figure_cls = _matplotlib()
    with text_settings():
        return _figure(figure_cls, timeline, title, numbers, on_panel)


def _figure(
    figure_cls: Any,
    timeline: Timeline,
    title: str | None,
    numbers: str,
    on_panel: Callable[[int, int], None] | None,
) -> Any:
    from matplotlib.patches import Patch

    shown = panels(timeline, numbers)
    heights = [
        0.45 * len(lane.series) + 0.55 if kind == "bars" else NUMBER_PANEL_HEIGHT
        for kind, lane in shown
    ]
    fig = figure_cls(figsize=(11, 1.1 + sum(heights)), layout="constrained")
    axes = fig.subplots(
        len(shown), 1, sharex=True, squeeze=False, gridspec_kw={"height_ratios": heights}
    )[:, 0]
    span = (timeline.until_ns - timeline.since_ns) / NS_PER_S
    for i, (ax, (kind, lane)) in enumerate(zip(axes, shown, strict=True), 1):
        if kind == "bars":
            _draw_lane(ax, lane, timeline, span)
        else:
            _draw_numbers(ax, lane, timeline)
        if on_panel is not None:
            on_panel(i, len(shown))
    _time_axis(axes[-1], timeline)
    facts = len({lane.label for _, lane in shown})
    fig.suptitle(
        title or f"toaster facts ({facts}), reference agent: {mpl_text(timeline.reference)}"
    )
    notes = [mpl_text(note) for note in legend_notes(timeline)]
    handles = [Patch(visible=False, label=note) for note in notes[2:]]  # A>B: no symbol
    if any(kind == "bars" for kind, _ in shown):
        handles = [
            Patch(facecolor="none", edgecolor="red", hatch="////", label=notes[0]),
            Patch(facecolor="none", edgecolor="grey", linestyle=":", label=notes[1]),
            Patch(
                facecolor="0.6",
                edgecolor="black",
                label="held value (opacity, black line = confidence)",
            ),
            *handles,
        ]
    if handles:
        fig.legend(
            handles=handles,
            loc="outside lower center",
            ncols=min(3, len(handles)),
            fontsize="small",
        )
    return fig


def _time_axis(ax: Any, timeline: Timeline) -> None:
    """x from the window start to its end, in seconds since the data's start; labelled as
    elapsed seconds or, for dates, with a UTC date at each tick."""
    axis = timeline.axis
    ax.set_xlim(axis.offset_s(timeline.since_ns), axis.offset_s(timeline.until_ns))
    ax.set_xlabel(axis.axis_label())
    if not axis.elapsed:
        from matplotlib.ticker import FuncFormatter

        ax.xaxis.set_major_formatter(
            FuncFormatter(lambda x, _pos: axis.show(axis.origin_ns + round(x * NS_PER_S)))
        )
        ax.tick_params(axis="x", labelrotation=15)


def _draw_numbers(ax: Any, lane: Lane, timeline: Timeline) -> None:
    """One post-step line per agent of the lane's number, broken where it does not hold (the
    reference agent solid and wide, the others dashed on top, so that equal numbers show)."""
    import matplotlib as mpl

    colours = mpl.colormaps["Dark2"]
    for signal in lane.signals:
        xs, ys = signal.steps(timeline.since_ns, timeline.until_ns, timeline.axis)
        reference = signal.agent == timeline.reference
        style = {"linewidth": 2.4} if reference else {"linewidth": 1.4, "linestyle": "--"}
        ax.plot(
            xs,
            ys,
            drawstyle="steps-post",
            label=mpl_text(f"{signal.agent} (reference)" if reference else signal.agent),
            color=colours(timeline.agents.index(signal.agent) % 8),
            gid=number_gid(lane, signal.agent),
            **style,
        )
    label = mpl_text(lane.number_label)
    ax.set_ylabel(label.replace(" (", "\n(") if len(label) > 18 else label, fontsize="small")
    ax.set_title(mpl_text(f"{lane.label}: number"), loc="left", fontsize="medium")
    ax.legend(loc="best", fontsize="small")
    ax.grid(alpha=0.3)


def _draw_lane(ax: Any, lane: Lane, timeline: Timeline, span: float) -> None:
    import matplotlib as mpl

    colours = mpl.colormaps["tab10"]
    x = timeline.axis.offset_s
    for row, series in enumerate(lane.series):
        ends = [c.t_ns for c in series.changes[1:]] + [timeline.until_ns]
        for change, end in zip(series.changes, ends, strict=True):
            if change.value is None:
                continue
            x0, width = x(change.t_ns), (end - change.t_ns) / NS_PER_S
            conf = 1.0 if change.confidence is None else change.confidence
            ax.broken_barh(
                [(x0, width)],
                (row - BAR / 2, BAR),
                facecolors=colours((change.level - 1) % 10),
                alpha=0.3 + 0.7 * conf,
                edgecolor="none",
            )
            y = row - BAR / 2 + BAR * conf
            ax.plot([x0, x0 + width], [y, y], color="black", linewidth=0.8)
            if width >= _MIN_LABEL_FRACTION * span:
                ax.text(
                    x0 + width / 2,
                    row,
                    mpl_text(f"{change.value} ({conf:.2g})"),
                    ha="center",
                    va="center",
                    fontsize="small",
                    clip_on=True,
                )
    agents = [s.agent for s in lane.series]
    for div in timeline.divergences:
        if div.lane != lane.label:
            continue
        row = agents.index(div.agent)
        x0, width = x(div.start_ns), (div.end_ns - div.start_ns) / NS_PER_S
        if div.kind == FALSE_BELIEF:
            style = {"facecolors": "none", "edgecolor": "red", "hatch": "////", "linewidth": 1.5}
        else:
            style = {"facecolors": "none", "edgecolor": "grey", "linestyle": ":"}
        ax.broken_barh([(x0, width)], (row - BAR / 2 - 0.08, BAR + 0.16), **style)
    ax.set_yticks(
        range(len(agents)),
        [mpl_text(f"{a} (reference)" if a == timeline.reference else a) for a in agents],
    )
    ax.set_ylim(len(agents) - 0.5, -0.5)
    ax.set_title(mpl_text(lane.label), loc="left", fontsize="medium", fontweight="bold")
    ax.grid(axis="x", alpha=0.3)
