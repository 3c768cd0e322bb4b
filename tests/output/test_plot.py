"""plot_facts: step data equal to the stored intervals, false beliefs, files, errors."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import toaster
from tests.output.conftest import T0, S, run_scenario
from toaster.errors import InvalidInputError, MissingDependencyError, UnknownAgentError
from toaster.plotting import FALSE_BELIEF, UNAWARE, Timeline, build_timeline, plot_facts
from toaster.queries import history

MAGIC = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}


def _spans(timeline: Timeline) -> set[tuple[str, str, int, int, str, float | None]]:
    """Held spans (lane, agent, start, end, value, confidence) read off the step functions."""
    out = set()
    for lane in timeline.lanes:
        for series in lane.series:
            ends = [c.t_ns for c in series.changes[1:]] + [timeline.until_ns]
            for change, end in zip(series.changes, ends, strict=True):
                if change.value is not None:
                    out.add((lane.label, series.agent, change.t_ns, end, change.value,
                             change.confidence))
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
        expected.add((label, row.agent_id, max(row.valid_from_ns, since), end, row.value_text,
                      row.confidence))
    assert _spans(timeline) == expected
    pr2 = next(lane for lane in timeline.lanes if lane.label == "alice Distance mug").series[0]
    assert [(c.t_ns - T0, c.value) for c in pr2.changes] == [
        (1 * S, "far"), (5 * S, "close"), (8 * S, "reach"), (14 * S, None)]


def test_false_belief_and_unawareness_stand_out(run_db: toaster.Database) -> None:
    """alice still believes the mug is on the table after the robot saw it moved at 10 s;
    bob, who never saw it there, is unaware until he learns it is on the shelf."""
    timeline = build_timeline(run_db, property="IsOn", until=T0 + 20 * S)
    assert timeline.reference == "pr2"
    found = {(d.lane, d.agent, d.start_ns - T0, d.end_ns - T0, d.kind)
             for d in timeline.divergences}
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
    out = plot_facts(run_db, tmp_path / "mug.dat", subject="mug", property="IsOn",
                     target="table", since=T0, until=T0 + 20 * S)
    assert out.companion is not None
    assert "with steps" in out.companion.read_text()
    blocks = [b for b in out.path.read_text().split("\n\n\n") if b.strip()]
    rows = {}
    for block in blocks:
        head = next(line for line in block.splitlines() if line.startswith("# fact:"))
        agent = head.split("agent: ")[1].split(" |")[0]
        rows[agent] = [line.split() for line in block.splitlines() if not line.startswith("#")]
    assert [(int(r[1]) - T0, int(r[2])) for r in rows["pr2"]] == [
        (0, 1), (10 * S, 0), (20 * S, 0)]
    assert [(int(r[1]) - T0, int(r[2]), r[4]) for r in rows["alice"]] == [
        (0, 0, '"-"'), (2 * S, 1, '"true"'), (20 * S, 1, '"true"')]
    assert rows["alice"][1][3] == "0.8"


def test_gnuplot_draws_the_script(run_db: toaster.Database, tmp_path: Path) -> None:
    """gnuplot, when installed, runs the generated script without an error."""
    import shutil
    import subprocess

    if shutil.which("gnuplot") is None:
        pytest.skip("gnuplot is not installed (apt-get install gnuplot-nox)")
    out = plot_facts(run_db, tmp_path / "all.dat")
    assert out.companion is not None
    script = f"set terminal svg\nset output 'all.svg'\n{out.companion.read_text()}"
    done = subprocess.run(["gnuplot"], input=script, text=True, cwd=tmp_path,
                          capture_output=True, check=False)
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


def test_missing_matplotlib_names_the_extra(run_db: toaster.Database, tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Without matplotlib a picture fails with the pip command; data files still work."""
    for name in [m for m in sys.modules if m.split(".")[0] == "matplotlib"]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(MissingDependencyError,
                       match=r"plot-facts needs matplotlib: pip install 'toaster\[plot\]'"):
        plot_facts(run_db, tmp_path / "x.png")
    assert plot_facts(run_db, tmp_path / "x.dat").path.exists()


def test_shipped_scenario_plots(tmp_path: Path) -> None:
    """A shipped scenario run through the producers plots; its step data equals its history."""
    db = toaster.connect(f"sqlite:///{tmp_path / 'flat.db'}")
    try:
        run_scenario(db, "scenario_flat.yaml", 30)
        for name in ("flat.png", "flat.dat"):
            out = plot_facts(db, tmp_path / name, subject=["alice", "mug"],
                             property=["IsInRoom", "IsInHand", "IsAt"])
            assert out.path.stat().st_size > 0
        timeline = out.timeline
        rows = history(db, subject=["alice", "mug"], property=["IsInRoom", "IsInHand", "IsAt"])
        # By default the agents are plotted, not the nested holders (alice>bob: name them).
        assert timeline.agents == ["pr2", "alice", "bob"]
        assert len(_spans(timeline)) == len([r for r in rows if ">" not in r.agent_id])
        keys = {(lane.key.subject_id, lane.key.property, lane.key.target_id)
                for lane in timeline.lanes}
        assert keys >= {("mug", "IsInHand", "alice"), ("alice", "IsInRoom", "Kitchen")}
        nested = plot_facts(db, tmp_path / "nested.dat", subject="mug",
                            agents=["pr2", "alice>bob"]).timeline
        assert nested.agents == ["pr2", "alice>bob"]
        assert any(span[1] == "alice>bob" for span in _spans(nested))
    finally:
        db.close()


def test_numbers_of_the_run_get_their_own_panel(run_db: toaster.Database,
                                                tmp_path: Path) -> None:
    """alice's Distance to the mug (3.0, 1.0, 0.4 m over three intervals) is drawn as one
    unbroken step line under its bars, and ends where the fact ends (14 s)."""
    from toaster.plotting.render import number_gid

    out = plot_facts(run_db, tmp_path / "run.svg", subject="alice", since=T0, until=T0 + 20 * S)
    lane = next(lane for lane in out.timeline.lanes if lane.label == "alice Distance mug")
    assert [s.agent for s in lane.signals] == ["pr2"]
    (line,) = [ln for ax in out.figure.axes for ln in ax.lines
               if ln.get_gid() == number_gid(lane, "pr2")]
    points = list(zip(line.get_xdata(), line.get_ydata(), strict=True))
    assert points[1:4] == [(1, 3.0), (5, 1.0), (8, 0.4)]
    assert points[-2][0] == 14
    assert [y != y for _, y in (points[0], points[-2])] == [True, True]  # NaN: not held
    assert line.axes.get_ylabel() == "Distance (m)"
    assert f'id="{number_gid(lane, "pr2")}"' in out.path.read_text()
