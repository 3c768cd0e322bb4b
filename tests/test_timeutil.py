"""Time that reads like the data: one parser, one formatter, and the data's start.

Durations count from when the database's data starts (recorded by runs, batches and belief
replays); tables show elapsed seconds for simulated data (starting in 1970) and dates for real
data; plots count their time axis from the data's start.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

import toaster
from toaster import Fact
from toaster.db.catalog import data_start_ns, note_data_start
from toaster.db.seed import load_file
from toaster.errors import InvalidInputError
from toaster.timeutil import (
    NS_PER_S,
    TimeFrame,
    format_ns,
    now_ns,
    parse_duration,
    parse_time,
)

S = NS_PER_S
REAL = parse_time("2026-11-22T12:00:00Z")  # data recorded on a real day


# -- the parser -----------------------------------------------------------------------------
def test_positive_durations_count_from_the_start() -> None:
    assert parse_time("12.5s", start_ns=REAL) == REAL + 12_500_000_000
    assert parse_time("+12.500 s", start_ns=REAL) == REAL + 12_500_000_000  # as tables show
    assert parse_time("250ms", start_ns=REAL) == REAL + 250_000_000
    assert parse_time("12.5s") == 12_500_000_000  # no start: the epoch


def test_minutes_are_m_or_min() -> None:
    assert parse_duration("3m") == parse_duration("3min") == 180 * S
    assert parse_time("1h", start_ns=5) == 5 + 3600 * S


def test_negative_durations_are_before_now() -> None:
    before = now_ns()
    got = parse_time("-5m", start_ns=REAL)
    after = now_ns()
    assert before - 300 * S <= got <= after - 300 * S


def test_ns_iso_and_now_ignore_the_start() -> None:
    assert parse_time("1700000000000000000", start_ns=REAL) == 1_700_000_000 * S
    assert parse_time("2026-11-22T12:00:00Z", start_ns=5 * S) == REAL
    assert parse_time("2026-11-22T13:00:00+01:00") == REAL
    before = now_ns()
    assert before <= parse_time("now", start_ns=REAL) <= now_ns()


@pytest.mark.parametrize("text", ["12 parsecs", "-5", "-300000d", "yesterday"])
def test_bad_times_are_one_line_errors_naming_them(text: str) -> None:
    with pytest.raises(InvalidInputError) as caught:
        parse_time(text, start_ns=REAL)
    message = str(caught.value)
    assert text in message and "\n" not in message


def test_a_duration_before_the_epoch_is_refused() -> None:
    with pytest.raises(InvalidInputError, match="out of range"):
        parse_time("-1000000h")  # 114 years ago


# -- the formatter --------------------------------------------------------------------------
def test_simulated_data_shows_elapsed_seconds() -> None:
    frame = TimeFrame(0)
    assert frame.elapsed
    assert frame.show(12_500_000_000) == "+12.500 s"
    assert frame.show(0) == "+0.000 s"
    assert frame.show(1_234_567) == "+0.001234567 s"  # never rounded away
    assert frame.show(None) == ""
    assert TimeFrame(S).show(0) == "-1.000 s"  # before the start


def test_real_data_shows_dates() -> None:
    frame = TimeFrame(REAL)
    assert not frame.elapsed
    assert frame.show(REAL + 500_000_000) == "2026-11-22 12:00:00.500Z"
    assert frame.show(REAL) == format_ns(REAL)


def test_the_style_switches_either_way() -> None:
    assert TimeFrame(REAL, "elapsed").show(REAL + 60 * S) == "+60.000 s"
    assert TimeFrame(0, "date").show(S) == "1970-01-01 00:00:01Z"
    assert not TimeFrame(None).elapsed  # nothing known: dates
    with pytest.raises(InvalidInputError, match="'relative'.*auto, elapsed, date"):
        TimeFrame(0, "relative")


@pytest.mark.parametrize("start", [0, 3 * S, REAL])
@pytest.mark.parametrize("style", ["elapsed", "date"])
def test_what_is_shown_reads_back(start: int, style: str) -> None:
    frame = TimeFrame(start, style)
    for t in (start, start + 12_500_000_000, start + 1_234_567, start + 86_400 * S):
        assert frame.parse(frame.show(t)) == t


def test_axis_values_count_from_the_start() -> None:
    assert TimeFrame(S).offset_s(7_400_000_000) == pytest.approx(6.4)
    assert TimeFrame(0).axis_label() == "seconds since the data's start"
    assert TimeFrame(REAL).axis_label() == "time (UTC)"


# -- the data's start -----------------------------------------------------------------------
@pytest.mark.slow
def test_the_earliest_start_is_kept(db: toaster.Database) -> None:
    with db.transaction(write=True) as conn:
        assert data_start_ns(conn) is None
        note_data_start(conn, REAL)
        note_data_start(conn, REAL + S)  # later: ignored
        assert data_start_ns(conn) == REAL
        note_data_start(conn, 5 * S)
        assert data_start_ns(conn) == 5 * S
    assert db.time_frame().start_ns == 5 * S
    assert db.time_frame("date").style == "date"
    db.store().empty()  # execute EMPTY ALL: no data, no start
    assert db.time_frame().start_ns is None


@pytest.mark.slow
def test_without_a_recorded_start_the_first_event_decides(store: toaster.Store) -> None:
    db = store.db
    assert db.time_frame().start_ns is None
    store.assert_fact("PR2_ROBOT", Fact("MUG", "IsOn", "TABLE"), t_ns=REAL + 7 * S)
    assert db.time_frame().start_ns == REAL + 7 * S
    store.assert_fact("PR2_ROBOT", Fact("MUG", "IsNear", "BOB"), t_ns=5 * S)
    assert db.time_frame().start_ns == 0  # simulated time: durations count from the epoch


SCENARIO = """\
name: clock
{start}duration: {duration}
rate: 2
self: pr2
entities:
  - {{id: pr2, kind: robot, self: true, position: [0, 0, 0]}}
  - {{id: bob, kind: human, position: [2, 0, 0], present: false}}
areas:
  Room: {{shape: circle, area_type: room, center: [0, 0], radius: 10}}
timeline:
  - {{at: {enter}, enter: bob, position: [2, 0, 0]}}
"""


def scenario(tmp_path: Path, *, start: str | None, enter: str, duration: str) -> Path:
    """A scenario where bob enters the room at ``enter`` after its start."""
    path = tmp_path / "clock.yaml"
    path.write_text(
        SCENARIO.format(start=f"start: {start}\n" if start else "", enter=enter, duration=duration),
        encoding="utf-8",
    )
    return path


def run_scenario(db: toaster.Database, path: Path) -> None:
    from toaster.producers import Runner, load_session

    session = load_session(path)
    store = db.store()
    runner = Runner(
        session.world,
        session.sources,
        session.producers,
        store=store,
        agent_id=session.self_id,
        config=session.config,
    )
    session.register(store)
    runner.run(session.start_ns, session.end_ns, session.rate_hz, maintain_every_s=None)


@pytest.mark.slow
@pytest.mark.parametrize("start", [None, "2026-11-22T12:00:00Z"])
def test_a_run_records_its_start(db: toaster.Database, tmp_path: Path, start: str | None) -> None:
    run_scenario(db, scenario(tmp_path, start=start, enter="2s", duration="4s"))
    expected = 0 if start is None else REAL
    assert db.time_frame().start_ns == expected
    assert db.time_frame().elapsed == (start is None)


@pytest.mark.slow
def test_batches_record_their_start(store: toaster.Store, tmp_path: Path) -> None:
    db = store.db
    dated = tmp_path / "dated.yaml"
    dated.write_text(
        "entities: [{id: ROOM, kind: area}]\n"
        "facts:\n"
        "  - {subject: MUG, property: IsOn, target: TABLE, at: 2026-11-22T12:05:00Z}\n"
        "  - {subject: MUG, property: IsIn, target: BOX, at: 2026-11-22T12:01:00Z}\n",
        encoding="utf-8",
    )
    load_file(store, dated)
    assert db.time_frame().start_ns == REAL + 60 * S  # its earliest row
    based = tmp_path / "based.yaml"
    based.write_text(
        "base_time: 2026-11-22T12:00:00Z\n"
        "facts: [{subject: MUG, property: IsNear, target: BOB, at: 90s}]\n",
        encoding="utf-8",
    )
    load_file(store, based)
    assert db.time_frame().start_ns == REAL  # what its durations count from
    simulated = tmp_path / "simulated.yaml"
    simulated.write_text(
        "facts: [{subject: BOB, property: IsIn, target: ROOM, at: 3s}]\n", encoding="utf-8"
    )
    load_file(store, simulated)
    assert db.time_frame().start_ns == 0  # durations from the epoch


@pytest.mark.slow
def test_a_belief_replay_starts_at_zero(db: toaster.Database) -> None:
    from toaster.beliefs import scenario as belief_scenario

    belief_scenario.replay(
        db, Path(toaster.__file__).parent / "examples" / "beliefs_sally_anne.yaml"
    )
    assert db.time_frame().start_ns == 0


@pytest.mark.slow
def test_plot_axis_counts_from_the_data_start(db: toaster.Database, tmp_path: Path) -> None:
    """A scenario starting at 0 whose first fact is at 1 s: the move at 6.4 s is at 6.4 on
    the axis (CSV time_s, the picture's step line), not at 5.4."""
    from toaster.outputs.plotting import plot_facts

    batch = tmp_path / "move.yaml"
    batch.write_text(
        "entities: [{id: PR2, kind: robot, self: true}, {id: BOB, kind: human},"
        " {id: MUG, kind: object}, {id: KITCHEN, kind: area}, {id: HALL, kind: area}]\n"
        "facts:\n"
        "  - {subject: MUG, property: IsIn, target: KITCHEN, at: 1s}\n"
        "  - {subject: MUG, property: Distance, target: BOB, num: 2.0, at: 1s}\n"
        "timeline:\n"
        "  - at: 6.4s\n"
        "    retract: [{subject: MUG, property: IsIn, target: NULL},\n"
        "              {subject: MUG, property: Distance, target: NULL}]\n"
        "    facts: [{subject: MUG, property: IsIn, target: HALL},\n"
        "            {subject: MUG, property: Distance, target: BOB, num: 3.0}]\n",
        encoding="utf-8",
    )
    load_file(db.store(), batch)
    out = plot_facts(db, tmp_path / "move.csv", subject="MUG", agents=["PR2"])
    with out.path.open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    moved = [r for r in rows if r["value_text"] == "true" and "HALL" in r["fact"]]
    assert [float(r["time_s"]) for r in moved] == [6.4]
    assert min(float(r["time_s"]) for r in rows) == 1.0
    pytest.importorskip("matplotlib")
    from toaster.outputs.plotting.render import number_gid

    picture = plot_facts(
        db, tmp_path / "move.png", subject="MUG", property="Distance", agents=["PR2"]
    )
    lane = picture.timeline.lanes[0]
    (line,) = [
        ln
        for ax in picture.figure.axes
        for ln in ax.lines
        if ln.get_gid() == number_gid(lane, "PR2")
    ]
    assert list(line.get_xdata())[:2] == [1.0, 6.4]
    axis = picture.figure.axes[-1]
    assert axis.get_xlim()[0] == 1.0
    assert axis.get_xlabel() == "seconds since the data's start"
    dated = plot_facts(
        db,
        tmp_path / "dated.png",
        subject="MUG",
        property="Distance",
        agents=["PR2"],
        frame=db.time_frame("date"),
    )
    axis = dated.figure.axes[-1]
    assert axis.get_xlabel() == "time (UTC)"
    assert axis.xaxis.get_major_formatter()(6.4, 0) == "1970-01-01 00:00:06.400Z"
