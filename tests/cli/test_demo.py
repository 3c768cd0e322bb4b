"""``toaster demo``: geometry -> facts -> Sally's false belief -> SQL -> a timeline picture."""

from __future__ import annotations

import re
import struct
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

import toaster
from tests.conftest import count
from toaster import Fact
from toaster.app.demo import SALLY, run_demo
from toaster.cli import cli

S = 1_000_000_000
#: From the scenario's timeline: Anne moves the marble into the box at 6.4 s, out of Sally's
#: sight; Sally opens the basket at 14 s.
MOVED, OPENED = 6_400_000_000, 14_000_000_000


def png_size(path: Path) -> tuple[int, int]:
    """Width and height of a PNG file (fails when it is not one)."""
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    width, height = struct.unpack(">II", head[16:24])
    return width, height


def one_fact(url: str) -> None:
    """A robot believing CUP IsOn TABLE in the database at ``url``."""
    with toaster.connect(url) as db:
        store = db.store()
        store.add_entity("R", "robot", is_self=True, t_ns=0)
        store.add_entities(
            [("CUP", "object", "", "", None), ("TABLE", "object", "", "", None)], t_ns=0
        )
        store.sync_snapshot("test", "R", S, [Fact("CUP", "IsOn", "TABLE")])


@pytest.mark.slow
def test_demo_tells_sallys_false_belief_in_a_fresh_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The README's first command: a fresh ./toaster-demo.db (an old one is replaced, the
    user's toaster.db is left alone), a story naming Sally's false belief, the SQL and its
    result, and a PNG timeline."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("TOASTER_DB", raising=False)
    mine = tmp_path / "toaster.db"
    runner = CliRunner()
    for url in ("sqlite:///toaster.db", "sqlite:///toaster-demo.db"):  # both hold a fact
        one_fact(url)
    before = mine.read_bytes()

    result = runner.invoke(cli, ["demo"])
    assert result.exit_code == 0, result.output
    out = result.output
    assert "Sally's false belief: the marble IsIn BASKET from +6.400 s" in out
    assert "to +14.000 s" in out
    lines = [re.split(r"\s{2,}", line.strip()) for line in out.splitlines()]
    header = next(cells for cells in lines if cells[:3] == ["time", "moment", "ROBOT"])
    row = next(cells for cells in lines if cells[0] == "+8.000 s")
    moved = dict(zip(header, row, strict=False))
    assert moved["ROBOT"] == "IsIn BOX" and moved["SALLY"] == "IsIn BASKET"
    assert row[-1] == "<- Sally's false belief"
    assert "FROM fact_history" in out
    sally_rows = [
        line.split()
        for line in out.splitlines()
        if line.strip().startswith("SALLY ") and "IsIn" in line
    ]
    assert sally_rows == [["SALLY", "IsIn", "BASKET", "+1.000", "s", "+14.000", "s"]]
    picture = tmp_path / "toaster-demo.png"
    assert str(picture) in out
    width, height = png_size(picture)
    assert 600 <= width <= 4000 and 400 <= height <= 4000
    assert picture.stat().st_size > 20_000  # bars, labels and a legend, not a blank page
    assert mine.read_bytes() == before
    with toaster.connect("sqlite:///toaster-demo.db") as db:  # recreated: the old fact is gone
        assert count(db, "SELECT count(*) FROM fact_keys WHERE subject_id = 'CUP'") == 0


@pytest.mark.slow
def test_run_demo_on_each_backend(empty_url: str, tmp_path: Path) -> None:
    """The library call behind the command: Sally's beliefs at each moment against the
    robot's, the SQL rows read-only, and the false-belief span the picture hatches."""
    with toaster.connect(empty_url) as db:
        demo = run_demo(db, tmp_path / "marble.png")
    by_time = {m.t_ns // S: m for m in demo.moments}
    assert by_time[2].sally == by_time[2].robot == ("IsIn BASKET",)
    assert not by_time[2].false
    for t in (8, 13):  # the marble is in the box; Sally, away then back, still thinks basket
        assert by_time[t].robot == ("IsIn BOX",)
        assert by_time[t].sally == by_time[t].anne_on_sally == ("IsIn BASKET",)
        assert [(d.target_id, d.value_a, d.value_b) for d in by_time[t].false] == [
            ("BASKET", "true", None)
        ]
    assert by_time[15].sally == () and by_time[15].robot == ("IsIn BOX",)
    rows = {(r[0], r[1], r[2]): (r[3], r[4]) for r in demo.result.rows}
    assert rows[(SALLY, "IsIn", "BASKET")] == (S, OPENED)
    assert rows[("ROBOT", "IsIn", "BOX")] == (MOVED, None)
    assert [(d.lane, d.start_ns, d.end_ns) for d in demo.divergences] == [
        ("MARBLE IsIn BASKET", MOVED, OPENED)
    ]
    assert demo.picture == tmp_path / "marble.png" and png_size(demo.picture)[0] > 600
    assert "***" not in demo.story()  # no password in what it prints


@pytest.mark.slow
def test_demo_refuses_a_database_that_holds_facts(db_url: str, tmp_path: Path) -> None:
    """--db must be empty: one line naming it, nothing written, no picture."""
    runner = CliRunner()
    one_fact(db_url)
    picture = tmp_path / "p.png"
    result = runner.invoke(cli, ["--db", db_url, "demo", "--picture", str(picture)])
    assert result.exit_code == 1
    assert "the demo needs an empty database" in result.output
    assert "already holds facts" in result.output and "Traceback" not in result.output
    assert not picture.exists()
    with toaster.connect(db_url) as db:
        assert count(db, "SELECT count(*) FROM entities WHERE id = 'SALLY'") == 0


@pytest.mark.slow
def test_demo_without_matplotlib_writes_gnuplot_data(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without the plot extra the timeline is gnuplot data, and the story says what to
    install for the PNG."""
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with toaster.connect(f"sqlite:///{tmp_path / 'd.db'}") as db:
        demo = run_demo(db, tmp_path / "t.png")
    assert demo.picture == tmp_path / "t.dat" and demo.picture.stat().st_size > 0
    assert demo.companion == tmp_path / "t.gp" and demo.companion.exists()
    assert not (tmp_path / "t.png").exists()
    story = demo.story()
    assert "pip install 'toaster[plot]'" in story
    assert f"gnuplot -p {tmp_path / 't.gp'}" in story


def test_demo_refuses_a_picture_it_cannot_write_before_running(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A bad --picture is one line naming it, before any database is made."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("TOASTER_DB", raising=False)
    for bad, said in (
        ("out.txt", "unknown plot file suffix of 'out.txt'"),
        ("no/such/dir/t.png", "'no/such/dir/t.png': its folder does not exist"),
    ):
        result = CliRunner().invoke(cli, ["demo", "--picture", bad])
        assert result.exit_code == 1
        assert said in result.output and "Traceback" not in result.output
    assert list(tmp_path.iterdir()) == []
