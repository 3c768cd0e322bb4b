"""plot-facts draws numbers (value_num) as step lines over time, refreshes included.

A Distance that moves beyond its tolerance (0.05 m) is refreshed in place and its earlier
numbers kept in ``fact_samples``: the picture, the .dat and the CSV show every stored number at
its time, not only the interval's last one, and a gap where the fact does not hold.
"""

from __future__ import annotations

import csv
import math
import re
import subprocess
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

import toaster
from tests.outputs.conftest import T0, S, open_built, require_gnuplot
from toaster import Fact
from toaster.cli.plot import plot_facts as plot_command
from toaster.errors import InvalidInputError
from toaster.outputs.plotting import build_timeline, plot_facts
from toaster.outputs.plotting.render import number_gid

NAN = float("nan")
SINCE, UNTIL = T0, T0 + 10 * S  # the plotted window
# pr2's Distance alice-mug: (seconds, metres) as stored; None = the fact does not hold
PR2_DISTANCE = [(0, None), (1, 1.0), (2, 1.3), (3, 1.8), (5, None), (7, 2.5), (9, None)]


def build_signals(db: toaster.Database) -> None:
    """pr2 measures alice's distance to the mug: 1.0, 1.3, 1.8 m at 1, 2, 3 s (1.82 m at
    3.5 s is within the 0.05 m tolerance), nothing from 5 s, 2.5 m from 7 s to 9 s; alice's
    speed 0.5 then 1.2 m/s; alice believes 2.0 m from 2 s to 6 s; the mug is on the table."""
    store = db.store()
    store.add_entity("pr2", "robot", is_self=True, t_ns=T0)
    store.add_entity("alice", "human", t_ns=T0)
    for thing in ("mug", "table"):
        store.add_entity(thing, "object", t_ns=T0)
    store.assert_fact("pr2", Fact("mug", "IsOn", "table", property_type="position"), t_ns=T0)
    dist = Fact("alice", "Distance", "mug", "close", 1.0, 0.9, property_type="position")
    moving = Fact(
        "alice", "IsMoving", "", "true", 0.5, 0.8, property_type="motion", sub_property="agent"
    )
    for t_s, metres, speed in ((1, 1.0, 0.5), (2, 1.3, 0.5), (3, 1.8, 1.2), (3.5, 1.82, 1.2)):
        store.sync_snapshot(
            "monitor",
            "pr2",
            T0 + int(t_s * S),
            [dist._replace(value_num=metres), moving._replace(value_num=speed)],
        )
    store.sync_snapshot("monitor", "pr2", T0 + 5 * S, [])
    store.sync_snapshot("monitor", "pr2", T0 + 7 * S, [dist._replace(value_num=2.5)])
    store.sync_snapshot("monitor", "pr2", T0 + 9 * S, [])
    store.sync_snapshot("monitor", "alice", T0 + 2 * S, [dist._replace(value_num=2.0)])
    store.sync_snapshot("monitor", "alice", T0 + 6 * S, [])


@pytest.fixture
def signal_db(db_url: str) -> Iterator[toaster.Database]:
    """An open database (SQLite and PostgreSQL) holding :func:`build_signals`."""
    yield from open_built(db_url, build_signals)


def _same(got: list[float], expected: list[float | None]) -> bool:
    """Equal lists where None / NaN both mean 'no number'."""
    return len(got) == len(expected) and all(
        (e is None and math.isnan(g)) or (e is not None and g == e)
        for g, e in zip(got, expected, strict=True)
    )


def _line(figure: Any, gid: str) -> tuple[Any, Any]:
    lines = [line for ax in figure.axes for line in ax.lines if line.get_gid() == gid]
    assert len(lines) == 1, [line.get_gid() for ax in figure.axes for line in ax.lines]
    return lines[0], lines[0].axes


@pytest.mark.slow
def test_number_line_holds_every_stored_value(signal_db: toaster.Database, tmp_path: Path) -> None:
    """The Distance line steps through 1.0, 1.3, 1.8 m at 1, 2, 3 s (not only the last 1.8),
    breaks while the fact does not hold and comes back at 2.5 m; the y axis says metres."""
    out = plot_facts(
        signal_db, tmp_path / "dist.png", property="Distance", since=SINCE, until=UNTIL
    )
    assert out.path.read_bytes().startswith(b"\x89PNG")
    lane = next(lane for lane in out.timeline.lanes if lane.label == "alice Distance mug")
    line, ax = _line(out.figure, number_gid(lane, "pr2"))
    assert line.get_drawstyle() == "steps-post"
    assert list(line.get_xdata()) == [t for t, _ in PR2_DISTANCE] + [10]
    assert _same(list(line.get_ydata()), [v for _, v in PR2_DISTANCE] + [None])
    assert ax.get_ylabel() == "Distance (m)"
    line, _ = _line(out.figure, number_gid(lane, "alice"))  # alice's belief, same panel
    assert list(line.get_xdata()) == [0, 2, 6, 10]
    assert _same(list(line.get_ydata()), [None, 2.0, None, None])


def _svg_paths(svg: Path, gid: str) -> list[list[tuple[float, float]]]:
    """The polylines (one per M ... L ... run) of the SVG group ``gid``, in SVG units."""
    group = next(g for g in ET.parse(svg).iter() if g.get("id") == gid)
    runs: list[list[tuple[float, float]]] = []
    for path in group.iter("{http://www.w3.org/2000/svg}path"):
        for cmd, x, y in re.findall(r"([ML])\s*(-?[\d.]+)\s+(-?[\d.]+)", path.get("d", "")):
            if cmd == "M":
                runs.append([])
            runs[-1].append((float(x), float(y)))
    return runs


@pytest.mark.slow
def test_svg_line_is_drawn_at_the_stored_values(
    signal_db: toaster.Database, tmp_path: Path
) -> None:
    """In the SVG file itself the number line has two runs (the gap), and its levels and
    steps sit where 1.0, 1.3, 1.8 m and 1, 2, 3 s put them on linear axes."""
    out = plot_facts(
        signal_db,
        tmp_path / "dist.svg",
        property="Distance",
        agents=["pr2"],
        since=SINCE,
        until=UNTIL,
    )
    assert out.path.read_bytes().startswith(b"<?xml")
    lane = out.timeline.lanes[0]
    runs = _svg_paths(out.path, number_gid(lane, "pr2"))
    assert len(runs) == 2  # 1 s to 5 s, then 7 s to 9 s
    first, second = runs
    xs = sorted({x for x, _ in first})
    ys = [y for _, y in first]
    levels = list(dict.fromkeys(ys))  # in drawing order: 1.0, 1.3, 1.8 m
    assert len(xs) == 4  # 1, 2, 3 and 5 s
    assert len(levels) == 3
    # affine axes: the ratios of the drawn offsets are those of the stored numbers and times
    assert (levels[1] - levels[0]) / (levels[2] - levels[0]) == pytest.approx(0.3 / 0.8, 1e-3)
    assert (xs[1] - xs[0]) / (xs[3] - xs[0]) == pytest.approx(1 / 4, 1e-3)
    assert (xs[2] - xs[0]) / (xs[3] - xs[0]) == pytest.approx(2 / 4, 1e-3)
    assert len({y for _, y in second}) == 1  # 2.5 m held from 7 s to 9 s
    y25 = second[0][1]
    assert (y25 - levels[0]) / (levels[2] - levels[0]) == pytest.approx(1.5 / 0.8, 1e-3)


def _number_blocks(dat: Path) -> dict[str, list[list[tuple[int, float, float]]]]:
    """agent -> held stretches of (t_ns, value_num, confidence) of the '# numbers:' blocks."""
    out = {}
    for block in dat.read_text().split("\n\n\n"):
        head = next((line for line in block.splitlines() if line.startswith("# numbers:")), None)
        if head is None:
            continue
        agent = head.split("agent: ")[1].split(" |")[0]
        stretches = []
        for chunk in block.split("\n\n"):
            rows = [line.split() for line in chunk.splitlines() if not line.startswith("#")]
            stretches.append([(int(r[1]) - T0, float(r[2]), float(r[3])) for r in rows])
        out[agent] = stretches
    return out


def test_dat_has_one_line_per_number(signal_db: toaster.Database, tmp_path: Path) -> None:
    """The .dat number block: one line per stored number at its time, each stretch closed at
    its end and followed by a blank line; the script draws it with steps and gnuplot runs it."""
    out = plot_facts(
        signal_db,
        tmp_path / "dist.dat",
        subject="alice",
        property="Distance",
        since=SINCE,
        until=UNTIL,
    )
    blocks = _number_blocks(out.path)
    assert blocks["pr2"] == [
        [(1 * S, 1.0, 0.9), (2 * S, 1.3, 0.9), (3 * S, 1.8, 0.9), (5 * S, 1.8, 0.9)],
        [(7 * S, 2.5, 0.9), (9 * S, 2.5, 0.9)],
    ]
    assert blocks["alice"] == [[(2 * S, 2.0, 0.9), (6 * S, 2.0, 0.9)]]
    assert "unit: m" in out.path.read_text()
    assert out.companion is not None
    script = out.companion.read_text()
    assert "using 1:3 with steps" in script
    assert "set ylabel 'Distance (m)' noenhanced" in script
    require_gnuplot()
    done = subprocess.run(
        ["gnuplot"],
        input=f"set terminal svg\nset output 'd.svg'\n{script}",
        text=True,
        cwd=tmp_path,
        capture_output=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "d.svg").stat().st_size > 1000


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_csv_has_one_row_per_number(signal_db: toaster.Database, tmp_path: Path) -> None:
    """The CSV's number rows are every stored number with its time (empty: not held); the
    state rows carry the number held when the state starts, not the interval's last one."""
    out = plot_facts(
        signal_db,
        tmp_path / "dist.csv",
        property="Distance",
        agents=["pr2"],
        since=SINCE,
        until=UNTIL,
    )
    rows = _csv_rows(out.path)
    numbers = [(int(r["t_ns"]) - T0, r["value_num"]) for r in rows if r["kind"] == "number"]
    assert numbers == [(t * S, "" if v is None else str(v)) for t, v in PR2_DISTANCE]
    number_rows = [r for r in rows if r["kind"] == "number" and r["value_num"]]
    assert {(r["value_text"], r["confidence"]) for r in number_rows} == {("close", "0.9")}
    states = [(int(r["t_ns"]) - T0, r["value_num"]) for r in rows if r["kind"] == "state"]
    assert states == [(0, ""), (1 * S, "1.0"), (5 * S, ""), (7 * S, "2.5"), (9 * S, "")]


@pytest.mark.slow
def test_numbers_modes(signal_db: toaster.Database, tmp_path: Path) -> None:
    """``only`` keeps the facts with numbers (one panel each, units on the y axes), ``off``
    draws today's bars only, and ``only`` without any number is a one-line error."""
    out = plot_facts(signal_db, tmp_path / "only.png", numbers="only", since=SINCE, until=UNTIL)
    labels = sorted(ax.get_ylabel() for ax in out.figure.axes)
    assert labels == ["Distance (m)", "IsMoving/agent\n(m/s)"]
    lane = next(lane for lane in out.timeline.lanes if lane.key.property == "IsMoving")
    line, _ = _line(out.figure, number_gid(lane, "pr2"))
    assert _same(list(line.get_ydata()), [None, 0.5, 1.2, None, None])
    rows = _csv_rows(
        plot_facts(signal_db, tmp_path / "only.csv", numbers="only", since=SINCE, until=UNTIL).path
    )
    assert {r["kind"] for r in rows} == {"number"}
    assert "mug IsOn table" not in {r["fact"] for r in rows}
    off = plot_facts(signal_db, tmp_path / "off.svg", numbers="off", since=SINCE, until=UNTIL)
    assert not any(line.get_gid() for ax in off.figure.axes for line in ax.lines)
    assert len(off.figure.axes) == 3  # Distance, IsMoving, IsOn bars
    rows = _csv_rows(
        plot_facts(signal_db, tmp_path / "off.csv", numbers="off", since=SINCE, until=UNTIL).path
    )
    assert {r["kind"] for r in rows} == {"state"}
    with pytest.raises(InvalidInputError, match="no numbers among the matching facts"):
        plot_facts(signal_db, tmp_path / "x.png", property="IsOn", numbers="only")
    with pytest.raises(InvalidInputError, match="unknown numbers mode 'lines'"):
        plot_facts(signal_db, tmp_path / "x.csv", numbers="lines")


@pytest.mark.slow
def test_timeline_signals_are_clipped_to_the_window(signal_db: toaster.Database) -> None:
    """A window starting inside a stretch starts with the number held then (1.3 m at 2.5 s)."""
    timeline = build_timeline(
        signal_db, property="Distance", agents=["pr2"], since=T0 + 2 * S + S // 2, until=T0 + 8 * S
    )
    (signal,) = timeline.lanes[0].signals
    assert [(p.t_ns - T0, p.value_num) for p in signal.points] == [
        (2 * S + S // 2, 1.3),
        (3 * S, 1.8),
        (5 * S, None),
        (7 * S, 2.5),
    ]
    assert not build_timeline(signal_db, property="Distance", numbers=False).number_lanes


@pytest.mark.slow
def test_plot_facts_command_numbers(
    signal_db: toaster.Database, db_url: str, tmp_path: Path
) -> None:
    """``toaster plot-facts out.csv --numbers only`` writes the number rows and says so."""
    out = tmp_path / "n.csv"
    done = CliRunner().invoke(
        plot_command,
        [
            str(out),
            "--numbers",
            "only",
            "-p",
            "Distance",
            "--from",
            str(T0),
            "--to",
            str(T0 + 10 * S),
            "--db",
            db_url,
        ],
    )
    assert done.exit_code == 0, done.output
    assert "1 facts, 1 with numbers" in done.output
    values = {r["value_num"] for r in _csv_rows(out) if r["agent"] == "pr2"}
    assert values == {"", "1.0", "1.3", "1.8", "2.5"}
