"""Timeline data files: gnuplot ``.dat`` (with the script that draws it) and CSV.

Both hold one line per change of a series (plus, in the ``.dat``, one closing line at the window
end so that gnuplot's ``with steps`` draws the last value to the end). Levels: 0 = the agent
does not hold the fact, k = it holds the lane's k-th value (listed in the header).

Facts that carry numbers add their number points (:class:`~toaster.plotting.timeline.Signal`):
in the ``.dat`` one block per (fact, agent) with one line per point (``time_s t_ns value_num
confidence``), each held stretch closed by a line at its end and a blank line (a gap for
gnuplot); in the CSV one row per point, ``kind`` = ``number``.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

from toaster.plotting.timeline import Signal, Timeline, check_numbers, panels
from toaster.timeutil import NS_PER_S, format_ns

CSV_COLUMNS = ("fact", "agent", "t_ns", "time_s", "value_text", "value_num", "confidence",
               "level", "diverges", "kind")


def _seconds(t_ns: int, since_ns: int) -> str:
    return f"{(t_ns - since_ns) / NS_PER_S:.9f}"


def _quoted(text: str) -> str:
    return '"' + text.replace("\\", "/").replace('"', "'") + '"'


def _diverges(timeline: Timeline, label: str, agent: str, t_ns: int) -> bool:
    return any(d.lane == label and d.agent == agent and d.start_ns <= t_ns < d.end_ns
               for d in timeline.divergences)


def _number(value: float | None) -> str:
    return "nan" if value is None else repr(float(value))


def _number_lines(signal: Signal, since_ns: int, until_ns: int) -> list[str]:
    """One line per held point; each held stretch ends with a line at its end time repeating
    the last number, then a blank line (gnuplot breaks the step line there)."""
    lines: list[str] = []
    points = signal.points
    for i, point in enumerate(points):
        if point.value_num is None:
            continue
        numbers = f"{_number(point.value_num)} {_number(point.confidence)}"
        lines.append(f"{_seconds(point.t_ns, since_ns)} {point.t_ns} {numbers}")
        after = points[i + 1] if i + 1 < len(points) else None
        if after is None or after.value_num is None:  # the stretch ends here
            end = until_ns if after is None else after.t_ns
            lines += [f"{_seconds(end, since_ns)} {end} {numbers}", ""]
    return lines[:-1] if lines else lines


def write_dat(timeline: Timeline, path: str | Path, numbers: str = "both") -> Path:
    """Write the gnuplot data file and, beside it, ``<name>.gp``; return the script's path.

    One data block per (fact, agent), blocks separated by two blank lines (gnuplot ``index``).
    Columns: seconds since the window start, time in ns, level, confidence, value. Facts that
    carry numbers add, after their own blocks, one block per agent with its numbers (header
    ``# numbers:``; columns: seconds, time in ns, value_num, confidence). ``numbers`` as in
    :func:`~toaster.plotting.render.render`.
    """
    path = Path(path)
    lines = [f"# toaster fact timeline from {format_ns(timeline.since_ns)} "
             f"to {format_ns(timeline.until_ns)} (window start = {timeline.since_ns} ns)",
             "# columns: time_s t_ns level confidence value   (level 0 = not believed)",
             "# '# numbers:' blocks: time_s t_ns value_num confidence   (one line per point; "
             "a blank line = the fact does not hold)",
             f"# draw it with: gnuplot -p {path.with_suffix('.gp').name}"]
    blocks = []
    for kind, lane in panels(timeline, numbers):
        if kind == "numbers":
            unit = lane.unit or "unknown unit"
            for signal in lane.signals:
                block = [f"# numbers: {lane.label} | agent: {signal.agent} | "
                         f"value_num: {lane.number_label} | unit: {unit}"]
                block += _number_lines(signal, timeline.since_ns, timeline.until_ns)
                blocks.append("\n".join(block))
            continue
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
    script.write_text(gnuplot_script(timeline, path.name, numbers), encoding="utf-8")
    return script


def gnuplot_script(timeline: Timeline, dat_name: str, numbers: str = "both") -> str:
    """The gnuplot commands that draw ``dat_name``: one panel per fact, one step line per agent,
    and one panel per fact's numbers (y: the property and its unit)."""
    shown = panels(timeline, numbers)
    out = [f"# gnuplot -p {Path(dat_name).with_suffix('.gp').name}",
           f"set multiplot layout {len(shown)},1 title "
           f"\"toaster facts from {format_ns(timeline.since_ns)}\"",
           "set key outside right", "set xlabel 'seconds since window start'",
           f"set xrange [0:{(timeline.until_ns - timeline.since_ns) / NS_PER_S:.9g}]"]
    index = 0
    for kind, lane in shown:
        if kind == "numbers":
            out += [f'set title "{lane.label}: {lane.number_label}"',
                    f'set ylabel "{lane.number_label}"', "set autoscale y", "set ytics auto"]
            plots = []
            for signal in lane.signals:
                plots.append(f"'{dat_name}' index {index} using 1:3 with steps lw 2 "
                             f'title "{signal.agent}"')
                index += 1
            out.append("plot " + ", \\\n     ".join(plots))
            continue
        tics = ", ".join([f"{_quoted(v)} {i}" for i, v in enumerate(lane.values, 1)])
        out += [f'set title "{lane.label}"', "unset ylabel",
                f"set yrange [-0.5:{len(lane.values) + 0.5}]",
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


def write_csv(timeline: Timeline, path: str | Path, numbers: str = "both") -> Path:
    """Write the step data as CSV, columns :data:`CSV_COLUMNS`: one row per change
    (``kind`` = ``state``) and, for facts that carry numbers, one row per number point
    (``kind`` = ``number``: value_num and confidence from then on, empty where the fact does
    not hold; value_text, level and diverges are the state's at that time). ``numbers`` as in
    :func:`~toaster.plotting.render.render`."""
    path = Path(path)
    check_numbers(numbers)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)
        def row(label: str, agent: str, t_ns: int, state: Any, number: Any, kind: str) -> None:
            writer.writerow([
                label, agent, t_ns, _seconds(t_ns, timeline.since_ns),
                *("" if v is None else v for v in (state.value, number.value_num,
                                                   number.confidence)),
                state.level, int(_diverges(timeline, label, agent, t_ns)), kind])

        for kind, lane in panels(timeline, numbers):
            if kind == "numbers":
                for signal in lane.signals:
                    series = next(s for s in lane.series if s.agent == signal.agent)
                    for point in signal.points:
                        row(lane.label, signal.agent, point.t_ns, series.value_at(point.t_ns),
                            point, "number")
                continue
            for series in lane.series:
                for change in series.changes:
                    row(lane.label, series.agent, change.t_ns, change, change, "state")
    return path
