"""Timeline data files: gnuplot ``.dat`` (with the script that draws it) and CSV.

Both hold one line per change of a series (plus, in the ``.dat``, one closing line at the window
end so that gnuplot's ``with steps`` draws the last value to the end). Levels: 0 = the agent
does not hold the fact, k = it holds the lane's k-th value (listed in the header).

Facts that carry numbers add their number points
(:class:`~toaster.outputs.plotting.timeline.Signal`):
in the ``.dat`` one block per (fact, agent) with one line per point (``time_s t_ns value_num
confidence``), each held stretch closed by a line at its end and a blank line (a gap for
gnuplot); in the CSV one row per point, ``kind`` = ``number``.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

from toaster.outputs.plotting.timeline import Signal, Timeline, check_numbers, holder_note, panels
from toaster.quoting import (
    csv_text,
    gnuplot_comment,
    gnuplot_datum,
    gnuplot_label,
    gnuplot_string,
    shell_word,
)
from toaster.timeutil import format_ns

CSV_COLUMNS = (
    "fact",
    "agent",
    "t_ns",
    "time_s",
    "value_text",
    "value_num",
    "confidence",
    "level",
    "diverges",
    "kind",
)


def _seconds(t_ns: int, timeline: Timeline) -> str:
    """The time axis value: seconds since the data's start (:attr:`Timeline.axis`)."""
    return f"{timeline.axis.offset_s(t_ns):.9f}"


def _diverges(timeline: Timeline, label: str, agent: str, t_ns: int) -> bool:
    return any(
        d.lane == label and d.agent == agent and d.start_ns <= t_ns < d.end_ns
        for d in timeline.divergences
    )


def _number(value: float | None) -> str:
    return "nan" if value is None else repr(float(value))


def _number_lines(signal: Signal, timeline: Timeline) -> list[str]:
    """One line per held point; each held stretch ends with a line at its end time repeating
    the last number, then a blank line (gnuplot breaks the step line there)."""
    lines: list[str] = []
    points = signal.points
    for i, point in enumerate(points):
        if point.value_num is None:
            continue
        numbers = f"{_number(point.value_num)} {_number(point.confidence)}"
        lines.append(f"{_seconds(point.t_ns, timeline)} {point.t_ns} {numbers}")
        after = points[i + 1] if i + 1 < len(points) else None
        if after is None or after.value_num is None:  # the stretch ends here
            end = timeline.until_ns if after is None else after.t_ns
            lines += [f"{_seconds(end, timeline)} {end} {numbers}", ""]
    return lines[:-1] if lines else lines


def write_dat(timeline: Timeline, path: str | Path, numbers: str = "both") -> Path:
    """Write the gnuplot data file and, beside it, ``<name>.gp``; return the script's path.

    One data block per (fact, agent), blocks separated by two blank lines (gnuplot ``index``).
    Columns: seconds since the data's start, time in ns, level, confidence, value. Facts that
    carry numbers add, after their own blocks, one block per agent with its numbers (header
    ``# numbers:``; columns: seconds, time in ns, value_num, confidence). ``numbers`` as in
    :func:`~toaster.outputs.plotting.render.render`.
    """
    path = Path(path)
    lines = [
        f"# toaster fact timeline from {format_ns(timeline.since_ns)} "
        f"to {format_ns(timeline.until_ns)} (window start = {timeline.since_ns} ns)",
        f"# time_s: seconds since the data's start, {format_ns(timeline.axis.origin_ns)} "
        f"({timeline.axis.origin_ns} ns)",
        "# columns: time_s t_ns level confidence value   (level 0 = not believed)",
        "# '# numbers:' blocks: time_s t_ns value_num confidence   (one line per point; "
        "a blank line = the fact does not hold)",
        gnuplot_comment("draw it with: gnuplot -p " + shell_word(path.with_suffix(".gp").name)),
    ]
    blocks = []
    for kind, lane in panels(timeline, numbers):
        if kind == "numbers":
            unit = lane.unit or "unknown unit"
            for signal in lane.signals:
                block = [
                    gnuplot_comment(
                        f"numbers: {lane.label} | agent: {signal.agent} | "
                        f"value_num: {lane.number_label} | unit: {unit}"
                    )
                ]
                block += _number_lines(signal, timeline)
                blocks.append("\n".join(block))
            continue
        codes = ", ".join(f"{i} = {v}" for i, v in enumerate(lane.values, 1))
        for series in lane.series:
            block = [
                gnuplot_comment(
                    f"fact: {lane.label} | agent: {series.agent} | levels: 0 = none, {codes}"
                )
            ]
            closing = series.changes[-1]._replace(t_ns=timeline.until_ns)
            for change in [*series.changes, closing]:
                conf = "nan" if change.confidence is None else f"{change.confidence:.6g}"
                value = '"-"' if change.value is None else gnuplot_datum(change.value)
                block.append(
                    f"{_seconds(change.t_ns, timeline)} {change.t_ns} {change.level} {conf} {value}"
                )
            blocks.append("\n".join(block))
    path.write_text("\n".join(lines) + "\n" + "\n\n\n".join(blocks) + "\n", encoding="utf-8")
    script = path.with_suffix(".gp")
    script.write_text(
        gnuplot_script(timeline, path.name, numbers, directory=str(path.resolve().parent)),
        encoding="utf-8",
    )
    return script


def _script_directory(fallback: str | None) -> list[str]:
    """gnuplot lines setting ``dir`` to the script's own directory (from ``ARG0``, the path
    it was run or loaded by), or to ``fallback`` when read from standard input."""
    slash = 'ARG0[i:i] eq "/" || ARG0[i:i] eq "\\\\"'
    lines = [
        'dir = ""',
        'if (exists("ARG0")) { do for [i=1:strlen(ARG0)] { if (' + slash + ") "
        "{ dir = ARG0[1:i] } } }",
    ]
    if fallback:
        sep = "" if fallback.endswith(("/", "\\")) else "/"
        lines.append(
            'if (!exists("ARG0") || strlen(ARG0) == 0) { dir = '
            + gnuplot_string(fallback + sep)
            + " }"
        )
    return lines


def gnuplot_script(
    timeline: Timeline, dat_name: str, numbers: str = "both", *, directory: str | None = None
) -> str:
    """The gnuplot commands that draw ``dat_name``: one panel per fact, one step line per agent,
    and one panel per fact's numbers (y: the property and its unit).

    The data file is read beside the script whatever the working directory (gnuplot's
    ``ARG0``: ``gnuplot -p some/dir/run.gp`` or ``load``); a script fed on standard input
    reads it from ``directory`` (absolute) if given, else from the working directory.
    The title says what each nested holder plotted means (``A>B = what A thinks B believes``).
    """
    shown, axis = panels(timeline, numbers), timeline.axis
    script = Path(dat_name).with_suffix(".gp").name
    data_path = (
        gnuplot_string(dat_name)
        if Path(dat_name).is_absolute()
        else f"dir . {gnuplot_string(dat_name)}"
    )
    height = 120 + 240 * len(shown)
    nested = [f"{a} = {holder_note(a)}" for a in timeline.agents if holder_note(a)]
    lines = [f"toaster facts from {format_ns(timeline.since_ns)}", *nested]
    title = ' . "\\n" . '.join(gnuplot_label(line) for line in lines)  # one line each
    out = [
        gnuplot_comment(
            f"gnuplot -p {shell_word(script)}   (from any directory: "
            f"{Path(dat_name).name} is read beside this script)"
        ),
        gnuplot_comment(
            f'a PNG: gnuplot -e "set terminal pngcairo size 1200,{height}; set '
            f"output 'facts.png'\" {shell_word(script)}"
        ),
        *_script_directory(directory),
        f"data = {data_path}",
        f"set multiplot layout {len(shown)},1 title {title} noenhanced",
        "set key outside right",
        "set xlabel "
        + gnuplot_label(f"seconds since the data's start ({format_ns(axis.origin_ns)})")
        + " noenhanced",
        f"set xrange [{axis.offset_s(timeline.since_ns):.9g}:"
        f"{axis.offset_s(timeline.until_ns):.9g}]",
    ]
    index = 0
    for kind, lane in shown:
        if kind == "numbers":
            out += [
                f"set title {gnuplot_label(f'{lane.label}: {lane.number_label}')} noenhanced",
                f"set ylabel {gnuplot_label(lane.number_label)} noenhanced",
                "set autoscale y",
                "set ytics auto",
            ]
            plots = []
            for signal in lane.signals:
                plots.append(
                    f"data index {index} using 1:3 with steps lw 2 "
                    f"title {gnuplot_label(signal.agent)} noenhanced"
                )
                index += 1
            out.append("plot " + ", \\\n     ".join(plots))
            continue
        tics = "".join(f", {gnuplot_label(v, tic=True)} {i}" for i, v in enumerate(lane.values, 1))
        out += [
            f"set title {gnuplot_label(lane.label)} noenhanced",
            "unset ylabel",
            f"set yrange [-0.5:{len(lane.values) + 0.5}]",
            f"set ytics ('none' 0{tics}) noenhanced",
        ]
        plots = []
        for k, series in enumerate(lane.series):
            offset = 0.06 * k  # keep agents' lines apart where they agree
            plots.append(
                f"data index {index} using 1:($3+{offset:g}) with steps "
                f"lw 2 title {gnuplot_label(series.agent)} noenhanced"
            )
            index += 1
        out.append("plot " + ", \\\n     ".join(plots))
    out.append("unset multiplot")
    return "\n".join(out) + "\n"


def write_csv(timeline: Timeline, path: str | Path, numbers: str = "both") -> Path:
    """Write the step data as CSV, columns :data:`CSV_COLUMNS`: one row per change
    (``kind`` = ``state``) and, for facts that carry numbers, one row per number point
    (``kind`` = ``number``: value_num and confidence from then on, empty where the fact does
    not hold; value_text, level and diverges are the state's at that time). ``numbers`` as in
    :func:`~toaster.outputs.plotting.render.render`. Text cells (fact, agent, value_text) that a
    spreadsheet would read as a formula start with ``'`` (:func:`toaster.quoting.csv_text`)."""
    path = Path(path)
    check_numbers(numbers)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)

        def row(label: str, agent: str, t_ns: int, state: Any, number: Any, kind: str) -> None:
            value = "" if state.value is None else csv_text(state.value)
            writer.writerow(
                [
                    csv_text(label),
                    csv_text(agent),
                    t_ns,
                    _seconds(t_ns, timeline),
                    value,
                    *("" if v is None else v for v in (number.value_num, number.confidence)),
                    state.level,
                    int(_diverges(timeline, label, agent, t_ns)),
                    kind,
                ]
            )

        for kind, lane in panels(timeline, numbers):
            if kind == "numbers":
                for signal in lane.signals:
                    series = next(s for s in lane.series if s.agent == signal.agent)
                    for point in signal.points:
                        row(
                            lane.label,
                            signal.agent,
                            point.t_ns,
                            series.value_at(point.t_ns),
                            point,
                            "number",
                        )
                continue
            for series in lane.series:
                for change in series.changes:
                    row(lane.label, series.agent, change.t_ns, change, change, "state")
    return path
