"""Recordings come back whole: ``toaster run`` on what ``toaster run --record`` wrote gives the
database of the run that recorded it, row for row (issue 27, item 3).

Compared, on every shipped scenario, as a rosbag2/MCAP folder and as a ROS 1 ``.bag``, on
SQLite (and one case on PostgreSQL): the entities, agents, belief holders (nested ones
included), areas, settings, belief chains, every fact interval with its key, its samples, every
event, the followed periods of the beliefs, and the ``fact_history`` / ``event_log`` views
(beliefs with their holders). Numbers are compared exactly: the recorded world is float64.

Not compared (and why):

* surrogate ids: ``facts.id``, ``fact_keys.id``, ``events.id``, ``belief_follow.id`` and the
  columns that point at them (``key_id``, ``fact_id``, ``hkey``, ``self_key``: each row is
  joined to its key's text instead), ``agents.num``;
* wall-clock columns: ``facts.recorded_ns``, ``events.recorded_ns`` (when the row was
  written), ``areas.updated_ns``, and ``entities.created_ns`` of the entities the store
  registers on its own when a fact names them (kind ``''``: a value such as ``normal``); the
  entities a run registers keep the data's time and are compared.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from click.testing import CliRunner

import toaster
from tests.conftest import pg_schema
from toaster.app.runs import run_file
from toaster.cli import cli

pytestmark = pytest.mark.slow  # each case runs a scenario twice (seconds)

pytest.importorskip("rosbags")

S = 1_000_000_000

EXAMPLES = Path(toaster.__file__).parent / "examples"
SCENARIOS = sorted(p.name for p in EXAMPLES.glob("scenario_*.yaml"))
KEY = (
    "k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, "
    "k.sub_property, k.target_id, k.target_owner_id"
)
FACT = "value_text, value_num, confidence, observability, valid_from_ns, valid_to_ns, source"
QUERIES = {
    "entities": "SELECT id, name, kind, owner_id, "
    "CASE WHEN kind = '' THEN NULL ELSE created_ns END FROM entities",
    "agents": "SELECT id, is_self, registered_ns FROM agents",
    "holders": "SELECT id, agent_id, depth, registered_ns FROM holders",
    "areas": "SELECT id, owner_id, spec_json FROM areas",
    "settings": 'SELECT scope, "key", value_json FROM settings',
    "belief_chain": "SELECT * FROM belief_chain",
    "facts": f"SELECT {KEY}, f.value_text, f.value_num, f.confidence, f.observability, "
    "f.valid_from_ns, f.valid_to_ns, f.source FROM facts f JOIN fact_keys k ON k.id = f.key_id",
    "fact_samples": f"SELECT {KEY}, f.valid_from_ns, s.until_ns, s.value_num, s.confidence, "
    "s.observability FROM fact_samples s JOIN facts f ON f.id = s.fact_id "
    "JOIN fact_keys k ON k.id = f.key_id",
    "events": f"SELECT {KEY}, e.agent_id, e.kind, e.stamp_ns, e.value_text, e.value_num, "
    "e.confidence, e.observability, e.previous_text, e.source "
    "FROM events e JOIN fact_keys k ON k.id = e.key_id",
    "belief_follow": f"SELECT w.holder_id, {KEY}, s.agent_id, s.subject_id, s.property, "
    "s.sub_property, s.target_id, w.from_ns, w.to_ns, w.events_from_ns, w.events_to_ns, "
    "w.pconf FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey "
    "JOIN fact_keys s ON s.id = w.self_key",
    "fact_history": "SELECT agent_id, subject_id, subject_owner_id, property, property_type, "
    f"sub_property, target_id, target_owner_id, {FACT} FROM fact_history",
    "event_log": "SELECT agent_id, kind, stamp_ns, subject_id, subject_owner_id, property, "
    "property_type, sub_property, target_id, target_owner_id, value_text, value_num, "
    "confidence, observability, previous_text, source FROM event_log",
}


def dump(url: str) -> dict[str, list[tuple[Any, ...]]]:
    """Every compared table and view of the database at ``url``, rows sorted."""
    with toaster.connect(url) as db, db.transaction() as conn:
        return {
            name: sorted((tuple(row) for row in conn.execute(sa.text(sql))), key=repr)
            for name, sql in QUERIES.items()
        }


def assert_same(original: str, replay: str) -> None:
    """The two databases hold the same rows (a readable diff of the first table that does
    not)."""
    a, b = dump(original), dump(replay)
    assert a["facts"], "the original run stored no fact"
    for name in QUERIES:
        missing = [r for r in a[name] if r not in b[name]][:5]
        extra = [r for r in b[name] if r not in a[name]][:5]
        assert a[name] == b[name], f"{name}: only in the run {missing}, only in the replay {extra}"


def round_trip(scenario: str, bag: Path, original: str, replay: str) -> None:
    """Run ``scenario`` into ``original`` recording ``bag``, then run ``bag`` into ``replay``."""
    with toaster.connect(original) as db:
        run_file(EXAMPLES / scenario, db, record_dir=bag)
    with toaster.connect(replay) as db:
        report = run_file(bag, db)
    assert report.notes == ()


@pytest.mark.parametrize("name", ["recording", "recording.bag"])
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_a_recording_replays_to_the_same_database(tmp_path: Path, scenario: str, name: str):
    first, second = f"sqlite:///{tmp_path / 'run.db'}", f"sqlite:///{tmp_path / 'replay.db'}"
    round_trip(scenario, tmp_path / name, first, second)
    assert_same(first, second)


@pytest.mark.postgresql
def test_a_recording_replays_to_the_same_database_on_postgresql(tmp_path: Path):
    with pg_schema() as first, pg_schema() as second:
        round_trip("scenario_spatial_sally_anne.yaml", tmp_path / "sally", first, second)
        assert_same(first, second)
        with toaster.connect(second) as db:
            (me,) = toaster.queries.agents(db, only_self=True)
            wrong = toaster.false_beliefs(db, "SALLY", at=10_000_000_000)
        assert me.id == "ROBOT"
        assert ("MARBLE", "IsIn", "BASKET") in {
            (d.subject_id, d.property, d.target_id) for d in wrong
        }


def test_sally_anne_comes_back_with_her_false_belief(tmp_path: Path):
    """The issue's case through the command line: the robot stays ROBOT, Sally and Anne hold
    beliefs, and Sally's false belief is there."""
    bag, first, second = tmp_path / "sally", tmp_path / "a.db", tmp_path / "b.db"
    runner = CliRunner()
    scenario = str(EXAMPLES / "scenario_spatial_sally_anne.yaml")
    result = runner.invoke(
        cli, ["--db", f"sqlite:///{first}", "run", scenario, "--record", str(bag)]
    )
    assert result.exit_code == 0, result.output
    result = runner.invoke(cli, ["--db", f"sqlite:///{second}", "run", str(bag)])
    assert result.exit_code == 0, result.output
    assert "note:" not in result.output
    diff = runner.invoke(
        cli, ["--db", f"sqlite:///{second}", "beliefs", "diff", "SALLY", "--at", "10s"]
    )
    assert diff.exit_code == 0, diff.output
    assert "BASKET" in diff.output
    with toaster.connect(f"sqlite:///{second}") as db:
        assert [a.id for a in toaster.queries.agents(db, only_self=True)] == ["ROBOT"]


def test_holders_and_config_given_at_replay_win(tmp_path: Path):
    """--holders and --config on the replay override the recorded ones."""
    bag = tmp_path / "sally.bag"
    with toaster.connect(f"sqlite:///{tmp_path / 'a.db'}") as db:
        run_file(
            EXAMPLES / "scenario_spatial_sally_anne.yaml",
            db,
            record_dir=bag,
            until_ns=2_000_000_000,
        )
    with toaster.connect(f"sqlite:///{tmp_path / 'b.db'}") as db:
        run_file(bag, db, holders="none", config={"presence_timeout": 5.0})
        agents = {a.id for a in toaster.queries.agents(db)}
    assert agents == {"ROBOT"}


def test_an_older_recording_replays_from_pdg_lists_with_a_note(tmp_path: Path):
    """A recording without /toaster/run and /toaster/world (as toaster wrote them before, and
    as ``record()`` writes without ``run``) replays from pdg's lists as before, and says in one
    line what it cannot reproduce."""
    from tests.outputs.conftest import run_scenario
    from toaster.outputs.recording import record

    bag = tmp_path / "old"
    with toaster.connect(f"sqlite:///{tmp_path / 'a.db'}") as db:
        frames = run_scenario(db, "scenario_spatial_sally_anne.yaml", 3.0)
        record(bag, frames, db=db)
    result = CliRunner().invoke(cli, ["--db", f"sqlite:///{tmp_path / 'b.db'}", "run", str(bag)])
    assert result.exit_code == 0, result.output
    notes = [line for line in result.output.splitlines() if line.startswith("note:")]
    assert len(notes) == 1
    assert "without /toaster/run" in notes[0]
    with toaster.connect(f"sqlite:///{tmp_path / 'b.db'}") as db:
        assert [a.id for a in toaster.queries.agents(db, only_self=True)] == ["toaster"]
        assert "SALLY" not in {a.id for a in toaster.queries.agents(db)}
        assert toaster.queries.history(db, "toaster")


def test_a_damaged_recorded_world_is_refused_in_one_line(tmp_path: Path):
    """A /toaster/world whose arrays do not fit its entities fails before anything is
    written, naming the bag."""
    from toaster.errors import FileFormatError
    from toaster.outputs.recording import Recorder
    from toaster.world.recorded import RunInfo

    info = RunInfo(0, S, "pr2", "humans", {}, {}, [("pr2", "robot", "pr2", "", "full")])
    bag = tmp_path / "bad.bag"
    with Recorder(bag) as rec:
        rec.write_run(info)
        rec.write_world(0, {"header": {"stamp": 0}, "ids": ["pr2"], "poses": [0.0] * 5})
    with (
        toaster.connect(f"sqlite:///{tmp_path / 'b.db'}") as db,
        pytest.raises(FileFormatError, match=r"bad.bag.*perceived_ns has 0, not 1"),
    ):
        run_file(bag, db)
    with toaster.connect(f"sqlite:///{tmp_path / 'b.db'}") as db:
        assert toaster.queries.agents(db) == []


@pytest.mark.parametrize("rate", [None, 1.0])
def test_a_recorded_track_file_replays_to_the_same_database(tmp_path: Path, rate):
    """A track file's run (on its sample times, or on a 1 Hz grid, with a gap in the samples)
    comes back on the same ticks."""
    import json

    samples = [(k * 0.4, "a", k * 0.3) for k in range(10)]
    samples += [(0.2 + k * 0.4, "b", 5.0 - k * 0.2) for k in range(8)] + [(7.0, "b", 1.0)]
    tracks = tmp_path / "t.jsonl"
    tracks.write_text(
        "".join(json.dumps({"t_s": t, "id": i, "x": x, "y": 1.0}) + "\n" for t, i, x in samples)
    )
    first, second = f"sqlite:///{tmp_path / 'a.db'}", f"sqlite:///{tmp_path / 'b.db'}"
    with toaster.connect(first) as db:
        ran = run_file(tracks, db, rate_hz=rate, record_dir=tmp_path / "rec")
    with toaster.connect(second) as db:
        again = run_file(tmp_path / "rec", db)
    assert again.stats.ticks == ran.stats.ticks
    assert_same(first, second)
