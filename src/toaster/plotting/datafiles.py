"""Timeline data files: gnuplot ``.dat`` (with the script that draws it) and CSV.

Both hold one line per change of a series (plus, in the ``.dat``, one closing line at the window
end so that gnuplot's ``with steps`` draws the last value to the end). Levels: 0 = the agent
does not hold the fact, k = it holds the lane's k-th value (listed in the header).
"""

from __future__ import annotations

import csv
from pathlib import Path

from toaster.plotting.timeline import Timeline
from toaster.timeutil import NS_PER_S, format_ns

CSV_COLUMNS = ("fact", "agent", "t_ns", "time_s", "value_text", "value_num", "confidence",
               "level", "diverges")


def _seconds(t_ns: int, since_ns: int) -> str:
    return f"{(t_ns - since_ns) / NS_PER_S:.9f}"


def _quoted(text: str) -> str:
    return '"' + text.replace("\\", "/").replace('"', "'") + '"'


def _diverges(timeline: Timeline, label: str, agent: str, t_ns: int) -> bool:
    return any(d.lane == label and d.agent == agent and d.start_ns <= t_ns < d.end_ns
               for d in timeline.divergences)


def write_dat(timeline: Timeline, path: str | Path) -> Path:
    """Write the gnuplot data file and, beside it, ``<name>.gp``; return the script's path.

    One data block per (fact, agent), blocks separated by two blank lines (gnuplot ``index``).
    Columns: seconds since the window start, time in ns, level, confidence, value.
    """
    path = Path(path)
    lines = [f"# toaster fact timeline from {format_ns(timeline.since_ns)} "
             f"to {format_ns(timeline.until_ns)} (window start = {timeline.since_ns} ns)",
             "# columns: time_s t_ns level confidence value   (level 0 = not believed)",
             f"# draw it with: gnuplot -p {path.with_suffix('.gp').name}"]
    blocks = []
    for lane in timeline.lanes:
        codes = ", ".join(f"{i} = {v}" for i, v in enumerate(lane.values, 1))
        for series in lane.series:
            block = [f"# fact: {lane.label} | agent: {series.agent} | levels: 0 = none, {codes}"]
            closing = series.changes[-1]._replace(t_ns=timeline.until_ns)
            for change in [*series.changes, closing]:
                conf = "nan" if change.confidence is None else f"{change.confidence:.6g}"
                value = '"-"' if change.value is None else _quoted(change.value)
                block.append(f"{_seconds(change.t_ns, timeline.since_ns)} {change.t_ns} "
                             f"{change.level} {conf} {value}")
            blocks.append("\n".join(block))
    path.write_text("\n".join(lines) + "\n" + "\n\n\n".join(blocks) + "\n", encoding="utf-8")
    script = path.with_suffix(".gp")
    script.write_text(gnuplot_script(timeline, path.name), encoding="utf-8")
    return script


def gnuplot_script(timeline: Timeline, dat_name: str) -> str:
    """The gnuplot commands that draw ``dat_name``: one panel per fact, one step line per agent."""
    lanes = timeline.lanes
    out = [f"# gnuplot -p {Path(dat_name).with_suffix('.gp').name}",
           f"set multiplot layout {len(lanes)},1 title "
           f"\"toaster facts from {format_ns(timeline.since_ns)}\"",
           "set key outside right", "set xlabel 'seconds since window start'",
           f"set xrange [0:{(timeline.until_ns - timeline.since_ns) / NS_PER_S:.9g}]"]
    index = 0
    for lane in lanes:
        tics = ", ".join([f"{_quoted(v)} {i}" for i, v in enumerate(lane.values, 1)])
        out += [f'set title "{lane.label}"', f"set yrange [-0.5:{len(lane.values) + 0.5}]",
                f'set ytics ("none" 0{", " + tics if tics else ""})']
        plots = []
        for k, series in enumerate(lane.series):
            offset = 0.06 * k  # keep agents' lines apart where they agree
            plots.append(f"'{dat_name}' index {index} using 1:($3+{offset:g}) with steps "
                         f'lw 2 title "{series.agent}"')
            index += 1
        out.append("plot " + ", \\\n     ".join(plots))
    out.append("unset multiplot")
    return "\n".join(out) + "\n"


def write_csv(timeline: Timeline, path: str | Path) -> Path:
    """Write the step data as CSV, one row per change, columns :data:`CSV_COLUMNS`."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)
        for lane in timeline.lanes:
            for series in lane.series:
                for change in series.changes:
                    writer.writerow([
                        lane.label, series.agent, change.t_ns,
                        _seconds(change.t_ns, timeline.since_ns),
                        "" if change.value is None else change.value,
                        "" if change.value_num is None else change.value_num,
                        "" if change.confidence is None else change.confidence,
                        change.level,
                        int(_diverges(timeline, lane.label, series.agent, change.t_ns))])
    return path
