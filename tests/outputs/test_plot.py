"""plot_facts: step data equal to the stored intervals, false beliefs, files, errors."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import toaster
from tests.outputs.conftest import T0, S, require_gnuplot, run_scenario
from toaster.errors import InvalidInputError, MissingDependencyError, UnknownAgentError
from toaster.outputs.plotting import FALSE_BELIEF, UNAWARE, Timeline, build_timeline, plot_facts
from toaster.queries import history

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

MAGIC = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}


def _spans(timeline: Timeline) -> set[tuple[str, str, int, int, str, float | None]]:
    """Held spans (lane, agent, start, end, value, confidence) read off the step functions."""
    out = set()
    for lane in timeline.lanes:
        for series in lane.series:
            ends = [c.t_ns for c in series.changes[1:]] + [timeline.until_ns]
            for change, end in zip(series.changes, ends, strict=True):
                if change.value is not None:
                    out.add(
                        (
                            lane.label,
                            series.agent,
                            change.t_ns,
                            end,
                            change.value,
                            change.confidence,
                        )
                    )
    return out


def test_step_data_matches_the_intervals_exactly(run_db: toaster.Database) -> None:
    """Every held span of the timeline is one stored interval clipped to the window, and
    every stored interval in the window shows up."""
    since, until = T0 + 1 * S, T0 + 15 * S
    timeline = build_timeline(run_db, since=since, until=until)
    expected = set()
    for row in history(run_db, since=since, until=until):
        label = " ".join(p for p in (row.subject_id, row.property, row.target_id) if p)
        end = until if row.valid_to_ns is None else min(row.valid_to_ns, until)
        expected.add(
            (
                label,
                row.agent_id,
                max(row.valid_from_ns, since),
                end,
                row.value_text,
                row.confidence,
            )
        )
    assert _spans(timeline) == expected
    pr2 = next(lane for lane in timeline.lanes if lane.label == "alice Distance mug").series[0]
    assert [(c.t_ns - T0, c.value) for c in pr2.changes] == [
        (1 * S, "far"),
        (5 * S, "close"),
        (8 * S, "reach"),
        (14 * S, None),
    ]


def test_false_belief_and_unawareness_stand_out(run_db: toaster.Database) -> None:
    """alice still believes the mug is on the table after the robot saw it moved at 10 s;
    bob, who never saw it there, is unaware until he learns it is on the shelf."""
    timeline = build_timeline(run_db, property="IsOn", until=T0 + 20 * S)
    assert timeline.reference == "pr2"
    found = {
        (d.lane, d.agent, d.start_ns - T0, d.end_ns - T0, d.kind) for d in timeline.divergences
    }
    assert ("mug IsOn table", "alice", 10 * S, 20 * S, FALSE_BELIEF) in found
    assert ("mug IsOn table", "bob", 0, 10 * S, UNAWARE) in found
    assert ("mug IsOn shelf", "bob", 10 * S, 16 * S, UNAWARE) in found
    assert not any(d.agent == "pr2" for d in timeline.divergences)


@pytest.mark.parametrize("fmt", ["png", "svg", "pdf"])
def test_pictures_are_written(run_db: toaster.Database, tmp_path: Path, fmt: str) -> None:
    """Each picture format gives a non-empty file of that format."""
    out = plot_facts(run_db, tmp_path / f"facts.{fmt}", subject="mug", agents=["pr2", "alice"])
    data = out.path.read_bytes()
    assert data.startswith(MAGIC[fmt])
    assert len(data) > 1000


def test_gnuplot_dat_has_one_line_per_change(run_db: toaster.Database, tmp_path: Path) -> None:
    """The .dat holds one line per change plus a closing line per series (not one every
    0.1 ms), with the level held *after* each change (the original inverted it)."""
    out = plot_facts(
        run_db,
        tmp_path / "mug.dat",
        subject="mug",
        property="IsOn",
        target="table",
        since=T0,
        until=T0 + 20 * S,
    )
    assert out.companion is not None
    assert "with steps" in out.companion.read_text()
    blocks = [b for b in out.path.read_text().split("\n\n\n") if b.strip()]
    rows = {}
    for block in blocks:
        head = next(line for line in block.splitlines() if line.startswith("# fact:"))
        agent = head.split("agent: ")[1].split(" |")[0]
        rows[agent] = [line.split() for line in block.splitlines() if not line.startswith("#")]
    assert [(int(r[1]) - T0, int(r[2])) for r in rows["pr2"]] == [(0, 1), (10 * S, 0), (20 * S, 0)]
    assert [(int(r[1]) - T0, int(r[2]), r[4]) for r in rows["alice"]] == [
        (0, 0, '"-"'),
        (2 * S, 1, '"true"'),
        (20 * S, 1, '"true"'),
    ]
    assert rows["alice"][1][3] == "0.8"


def test_gnuplot_draws_the_script(run_db: toaster.Database, tmp_path: Path) -> None:
    """gnuplot runs the generated script without an error."""
    import subprocess

    require_gnuplot()
    out = plot_facts(run_db, tmp_path / "all.dat")
    assert out.companion is not None
    script = f"set terminal svg\nset output 'all.svg'\n{out.companion.read_text()}"
    done = subprocess.run(
        ["gnuplot"], input=script, text=True, cwd=tmp_path, capture_output=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "all.svg").stat().st_size > 1000


def test_csv_step_data_reads_into_pandas(run_db: toaster.Database, tmp_path: Path) -> None:
    """The CSV has one row per change with the divergence flag."""
    pd = pytest.importorskip("pandas")
    out = plot_facts(run_db, tmp_path / "steps.csv", property="IsOn", until=T0 + 20 * S)
    frame = pd.read_csv(out.path, keep_default_na=False)
    alice = frame[(frame.agent == "alice") & (frame.fact == "mug IsOn table")]
    assert list(alice.t_ns - T0) == [0, 2 * S]
    assert list(alice.diverges) == [1, 0]  # unaware at first; the 10 s divergence has no row
    assert set(frame.agent) == {"pr2", "alice", "bob"}


def test_bad_input_gives_one_line_errors(run_db: toaster.Database, tmp_path: Path) -> None:
    """Unknown agent, empty window, unknown format and no matching fact name the problem."""
    with pytest.raises(UnknownAgentError, match="unknown agent 'carol': known agents are"):
        plot_facts(run_db, tmp_path / "x.png", agents=["carol"])
    with pytest.raises(InvalidInputError, match="empty time window"):
        plot_facts(run_db, tmp_path / "x.csv", since=T0 + 5 * S, until=T0 + 5 * S)
    with pytest.raises(InvalidInputError, match=r"unknown plot file suffix of .*x\.bmp"):
        plot_facts(run_db, tmp_path / "x.bmp")
    with pytest.raises(InvalidInputError, match="no fact matches subject='teapot'"):
        plot_facts(run_db, tmp_path / "x.csv", subject="teapot")


def test_missing_matplotlib_names_the_extra(
    run_db: toaster.Database, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without matplotlib a picture fails with the pip command; data files still work."""
    for name in [m for m in sys.modules if m.split(".")[0] == "matplotlib"]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(
        MissingDependencyError, match=r"plot-facts needs matplotlib: pip install 'toaster\[plot\]'"
    ):
        plot_facts(run_db, tmp_path / "x.png")
    assert plot_facts(run_db, tmp_path / "x.dat").path.exists()


def test_shipped_scenario_plots(tmp_path: Path) -> None:
    """A shipped scenario run through the producers plots; its step data equals its history."""
    db = toaster.connect(f"sqlite:///{tmp_path / 'flat.db'}")
    try:
        run_scenario(db, "scenario_flat.yaml", 30)
        for name in ("flat.png", "flat.dat"):
            out = plot_facts(
                db,
                tmp_path / name,
                subject=["alice", "mug"],
                property=["IsInRoom", "IsInHand", "IsAt"],
            )
            assert out.path.stat().st_size > 0
        timeline = out.timeline
        rows = history(db, subject=["alice", "mug"], property=["IsInRoom", "IsInHand", "IsAt"])
        # By default the agents are plotted, not the nested holders (alice>bob: name them).
        assert timeline.agents == ["pr2", "alice", "bob"]
        assert len(_spans(timeline)) == len([r for r in rows if ">" not in r.agent_id])
        keys = {
            (lane.key.subject_id, lane.key.property, lane.key.target_id) for lane in timeline.lanes
        }
        assert keys >= {("mug", "IsInHand", "alice"), ("alice", "IsInRoom", "Kitchen")}
        nested = plot_facts(
            db, tmp_path / "nested.dat", subject="mug", agents=["pr2", "alice>bob"]
        ).timeline
        assert nested.agents == ["pr2", "alice>bob"]
        assert any(span[1] == "alice>bob" for span in _spans(nested))
    finally:
        db.close()


def test_numbers_of_the_run_get_their_own_panel(run_db: toaster.Database, tmp_path: Path) -> None:
    """alice's Distance to the mug (3.0, 1.0, 0.4 m over three intervals) is drawn as one
    unbroken step line under its bars, and ends where the fact ends (14 s)."""
    from toaster.outputs.plotting.render import number_gid

    out = plot_facts(run_db, tmp_path / "run.svg", subject="alice", since=T0, until=T0 + 20 * S)
    lane = next(lane for lane in out.timeline.lanes if lane.label == "alice Distance mug")
    assert [s.agent for s in lane.signals] == ["pr2"]
    (line,) = [
        ln for ax in out.figure.axes for ln in ax.lines if ln.get_gid() == number_gid(lane, "pr2")
    ]
    points = list(zip(line.get_xdata(), line.get_ydata(), strict=True))
    assert points[1:4] == [(1, 3.0), (5, 1.0), (8, 0.4)]
    assert points[-2][0] == 14
    assert [y != y for _, y in (points[0], points[-2])] == [True, True]  # NaN: not held
    assert line.axes.get_ylabel() == "Distance (m)"
    assert f'id="{number_gid(lane, "pr2")}"' in out.path.read_text()


def test_the_most_relevant_facts_are_kept(run_db: toaster.Database, tmp_path: Path) -> None:
    """With a cap, false beliefs come first (alice's mug on the table), then the facts that
    change most (the robot's distance to alice, four values), and the result says how many
    matching facts were left out; 0 draws every fact."""

    def kept(max_facts: int) -> tuple[list[str], int]:
        out = plot_facts(run_db, tmp_path / "capped.csv", max_facts=max_facts)
        return [lane.label for lane in out.timeline.lanes], out.left_out

    assert kept(1) == (["mug IsOn table"], 2)
    assert kept(2) == (["alice Distance mug", "mug IsOn table"], 1)
    assert kept(0) == (["alice Distance mug", "mug IsOn shelf", "mug IsOn table"], 0)
    capped = plot_facts(run_db, tmp_path / "capped.png", max_facts=1)
    assert [ax.get_title(loc="left") for ax in capped.figure.axes] == ["mug IsOn table"]
    assert {d.lane for d in capped.timeline.divergences} == {"mug IsOn table"}
    with pytest.raises(InvalidInputError, match="max facts -1 is negative"):
        plot_facts(run_db, tmp_path / "x.csv", max_facts=-1)


def test_progress_is_reported_per_panel(run_db: toaster.Database, tmp_path: Path) -> None:
    """plot_facts tells a progress callback what it does: reading, one call per panel drawn,
    saving."""
    calls: list[tuple[str, int, int | None]] = []
    out = plot_facts(run_db, tmp_path / "p.png", progress=lambda *call: calls.append(call))
    panels = len(out.figure.axes)
    assert calls[0][0] == "reading facts" and calls[-1][0] == "saving"
    assert [c for c in calls if c[0] == "drawing"] == [
        ("drawing", i, panels) for i in range(1, panels + 1)
    ]


def _changes(lane: object) -> int:
    """Changes of value and of number of a lane (the relevance rule's third criterion)."""
    return (
        sum(len(s.changes) - 1 for s in lane.series)  # type: ignore[attr-defined]
        + sum(len(g.points) - 1 for g in lane.signals)
    )  # type: ignore[attr-defined]


def test_unfiltered_plot_of_a_large_replay_is_capped(db_url: str, tmp_path: Path) -> None:
    """plot-facts with no filter on 200 s of the ETH hotel replay (about 200 facts) draws the
    20 facts that change most, in bounded time and size, and says on stderr how many it left
    out and how to choose others."""
    import time

    from click.testing import CliRunner

    from tests.conftest import shared_data
    from toaster.app.runs import run_file
    from toaster.cli.plot import plot_facts as command
    from toaster.outputs.plotting import MAX_FACTS

    obsmat = shared_data("eth-ucy-opentraj", "ETH", "seq_hotel", "obsmat.txt")
    db = toaster.connect(db_url)
    try:
        run_file(obsmat, db, holders="none", until_ns=200 * S)
        every = build_timeline(db)
    finally:
        db.close()
    assert len(every.lanes) > 5 * MAX_FACTS
    started = time.perf_counter()
    done = CliRunner().invoke(command, [str(tmp_path / "eth.png"), "--db", db_url])
    elapsed = time.perf_counter() - started
    assert done.exit_code == 0, done.output
    assert elapsed < 120  # unbounded, it ran past 300 s
    assert f"({MAX_FACTS} facts," in done.stdout
    left = len(every.lanes) - MAX_FACTS
    assert f"{left} more matched and were left out" in done.stderr
    assert "--subject" in done.stderr and "--max-facts" in done.stderr
    width, height = _png_size(tmp_path / "eth.png")
    assert width < 2000 and height < 10_000
    db = toaster.connect(db_url)
    try:
        kept = plot_facts(db, tmp_path / "eth.csv").timeline.lanes
    finally:
        db.close()
    shown = {lane.label for lane in kept}
    assert len(shown) == MAX_FACTS
    left_out = [lane for lane in every.lanes if lane.label not in shown]
    assert min(_changes(lane) for lane in kept) >= max(_changes(lane) for lane in left_out)


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head.startswith(MAGIC["png"])
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def _table_curves(path: Path) -> dict[str, list[list[tuple[float, float]]]]:
    """The curves gnuplot plotted in ``set table`` mode, by title (one list per panel)."""
    curves: dict[str, list[list[tuple[float, float]]]] = {}
    points: list[tuple[float, float]] = []
    for line in path.read_text().splitlines():
        if line.startswith("# Curve title:"):
            points = []
            curves.setdefault(line.split('"')[1], []).append(points)
        elif line.strip() and not line.startswith("#"):
            x, y, _ = line.split()
            points.append((float(x), float(y)))
    return curves


def test_gnuplot_runs_from_any_directory(run_db: toaster.Database, tmp_path: Path) -> None:
    """The .gp reads its .dat beside itself whether gnuplot runs it from its own folder,
    from another one by a relative or absolute path, or reads it on standard input; the
    number panel plots alice's distance as stored (3.0, 1.0, 0.4 m from 1, 5, 8 s to 14 s)."""
    import subprocess

    gnuplot = require_gnuplot()
    (tmp_path / "out").mkdir()
    (tmp_path / "elsewhere").mkdir()
    out = plot_facts(run_db, tmp_path / "out" / "run.dat", subject="alice", until=T0 + 20 * S)
    assert out.companion is not None
    x = out.timeline.axis.offset_s
    want = [(x(T0 + t * S), metres) for t, metres in ((1, 3.0), (5, 1.0), (8, 0.4), (14, 0.4))]
    script = out.companion.read_text()
    runs = {
        "own folder": (tmp_path / "out", ["run.gp"], None),
        "relative": (tmp_path / "elsewhere", ["../out/run.gp"], None),
        "absolute": (tmp_path / "elsewhere", [str(out.companion)], None),
        "stdin": (tmp_path / "elsewhere", ["-"], script),
    }
    for name, (cwd, args, stdin) in runs.items():
        table = tmp_path / f"{name}.txt"
        done = subprocess.run(
            [gnuplot, "-e", f"set table '{table}'", *args],
            cwd=cwd,
            input=stdin,
            text=True,
            capture_output=True,
            check=False,
        )
        assert done.returncode == 0, (name, done.stderr)
        assert "Cannot find" not in done.stderr, (name, done.stderr)
        curves = _table_curves(table)
        number_panel = curves["pr2"][-1]
        assert [(round(a, 6), b) for a, b in number_panel] == [(round(a, 6), b) for a, b in want], (
            name
        )


@pytest.fixture
def sally_anne_db(db_url: str) -> Iterator[toaster.Database]:
    """The Sally-Anne belief replay: Anne believes Sally still believes the marble is in the
    basket (ANNE>SALLY, a nested holder) after Anne moved it to the box."""
    from importlib.resources import files

    from tests.outputs.conftest import open_built
    from toaster.beliefs.scenario import replay

    def build(db: toaster.Database) -> None:
        replay(db, Path(str(files("toaster") / "examples" / "beliefs_sally_anne.yaml")))

    yield from open_built(db_url, build)


def test_legend_says_what_a_nested_holder_is(
    sally_anne_db: toaster.Database, tmp_path: Path
) -> None:
    """A plot showing ANNE>SALLY says in its legend (picture) and title (gnuplot) that it is
    what Anne thinks Sally believes, beside what the red hatching means; without nested
    holders, no such line."""
    agents = ["ROBOT", "SALLY", "ANNE", "ANNE>SALLY"]
    note = "ANNE>SALLY = what ANNE thinks SALLY believes"
    out = plot_facts(sally_anne_db, tmp_path / "sa.png", subject="MARBLE", agents=agents)
    (legend,) = out.figure.legends
    texts = [t.get_text() for t in legend.get_texts()]
    assert note in texts
    assert "false belief: holds a value ROBOT (reference) does not" in texts
    assert any(d.agent == "ANNE>SALLY" and d.kind == FALSE_BELIEF for d in out.timeline.divergences)
    dat = plot_facts(sally_anne_db, tmp_path / "sa.dat", subject="MARBLE", agents=agents)
    assert dat.companion is not None
    assert note in dat.companion.read_text()
    plain = plot_facts(
        sally_anne_db, tmp_path / "plain.png", subject="MARBLE", agents=["ROBOT", "SALLY"]
    )
    assert not [t for t in plain.figure.legends[0].get_texts() if ">" in t.get_text()]
