"""Drawing a :class:`~toaster.plotting.timeline.Timeline` with matplotlib (the ``plot`` extra).

One panel per fact, one row per agent. A bar is a held value (its colour is the value, its
opacity and the thin black line inside it the confidence); red hatching marks a false belief
(the agent holds a value the reference agent does not), grey dots a fact the agent is unaware
of. matplotlib is imported here only, and only through :class:`matplotlib.figure.Figure`, so
no GUI backend and no global pyplot state are involved.
"""

from __future__ import annotations

from typing import Any

from toaster.errors import MissingDependencyError
from toaster.plotting.timeline import FALSE_BELIEF, Lane, Timeline
from toaster.timeutil import NS_PER_S, format_ns

BAR = 0.6
_MIN_LABEL_FRACTION = 0.06


def _matplotlib() -> Any:
    try:
        from matplotlib.figure import Figure
    except ImportError:
        package = "matplotlib"
        raise MissingDependencyError(package, "plot", "plot-facts") from None
    return Figure


def render(timeline: Timeline, *, title: str | None = None) -> Any:
    """A matplotlib ``Figure`` of the timeline (save it with ``fig.savefig(path)``)."""
    figure_cls = _matplotlib()
    from matplotlib.patches import Patch

    lanes = timeline.lanes
    rows = [len(lane.series) for lane in lanes]
    fig = figure_cls(figsize=(11, 1.1 + sum(0.45 * r + 0.55 for r in rows)),
                     layout="constrained")
    axes = fig.subplots(len(lanes), 1, sharex=True, squeeze=False,
                        gridspec_kw={"height_ratios": [r + 0.6 for r in rows]})[:, 0]
    span = (timeline.until_ns - timeline.since_ns) / NS_PER_S
    for ax, lane in zip(axes, lanes, strict=True):
        _draw_lane(ax, lane, timeline, span)
    axes[-1].set_xlim(0, span)
    axes[-1].set_xlabel(f"seconds since {format_ns(timeline.since_ns)}")
    fig.suptitle(title or f"toaster facts ({len(lanes)}), reference agent: {timeline.reference}")
    handles = [Patch(facecolor="none", edgecolor="red", hatch="////", label="false belief"),
               Patch(facecolor="none", edgecolor="grey", linestyle=":", label="unaware"),
               Patch(facecolor="0.6", edgecolor="black", label="held value (opacity, black line"
                                                               " = confidence)")]
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize="small")
    return fig


def _draw_lane(ax: Any, lane: Lane, timeline: Timeline, span: float) -> None:
    import matplotlib as mpl

    colours = mpl.colormaps["tab10"]
    since = timeline.since_ns
    for row, series in enumerate(lane.series):
        ends = [c.t_ns for c in series.changes[1:]] + [timeline.until_ns]
        for change, end in zip(series.changes, ends, strict=True):
            if change.value is None:
                continue
            x0, width = (change.t_ns - since) / NS_PER_S, (end - change.t_ns) / NS_PER_S
            conf = 1.0 if change.confidence is None else change.confidence
            ax.broken_barh([(x0, width)], (row - BAR / 2, BAR),
                           facecolors=colours((change.level - 1) % 10),
                           alpha=0.3 + 0.7 * conf, edgecolor="none")
            y = row - BAR / 2 + BAR * conf
            ax.plot([x0, x0 + width], [y, y], color="black", linewidth=0.8)
            if width >= _MIN_LABEL_FRACTION * span:
                ax.text(x0 + width / 2, row, f"{change.value} ({conf:.2g})", ha="center",
                        va="center", fontsize="small", clip_on=True)
    agents = [s.agent for s in lane.series]
    for div in timeline.divergences:
        if div.lane != lane.label:
            continue
        row = agents.index(div.agent)
        x0, width = (div.start_ns - since) / NS_PER_S, (div.end_ns - div.start_ns) / NS_PER_S
        if div.kind == FALSE_BELIEF:
            style = {"facecolors": "none", "edgecolor": "red", "hatch": "////", "linewidth": 1.5}
        else:
            style = {"facecolors": "none", "edgecolor": "grey", "linestyle": ":"}
        ax.broken_barh([(x0, width)], (row - BAR / 2 - 0.08, BAR + 0.16), **style)
    ax.set_yticks(range(len(agents)),
                  [f"{a} (reference)" if a == timeline.reference else a for a in agents])
    ax.set_ylim(len(agents) - 0.5, -0.5)
    ax.set_title(lane.label, loc="left", fontsize="medium", fontweight="bold")
    ax.grid(axis="x", alpha=0.3)
