"""Regression tests for issue 14's fuzz findings: each command a shell could type, its one-line
error (exit 1, or 2 for click usage errors), and a database left exactly as it was."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
import sqlalchemy as sa
from click.testing import CliRunner, Result

import toaster
from tests.cli.test_fuzz import EXAMPLES, dump
from toaster.beliefs import api
from toaster.cli import cli
from toaster.model import MAX_ID_BYTES, check_id
from toaster.timeutil import parse_duration, parse_time

Fails = Callable[..., Result]


def seed(url: str) -> None:
    """The demo's batch and a tolerance: data a failed command must leave as it was."""
    runner = CliRunner()
    for args in (
        ["set-info", "--file", str(EXAMPLES / "demo_mug.yaml")],
        ["tolerance", "Distance", "0.05"],
    ):
        assert runner.invoke(cli, ["--db", url, *args]).exit_code == 0


def checker(url: str) -> Fails:
    """``fails(*args, message=...)`` on ``url``: the command exits 1 (or ``code``) with one
    ``Error`` line holding ``message``, no traceback, and every table as it was."""
    runner = CliRunner()

    def invoke(*args: str, message: str, code: int = 1) -> Result:
        before = dump(url)
        result = runner.invoke(cli, ["--db", url, *args])
        assert result.exception is None or isinstance(result.exception, SystemExit), (
            args,
            result.exception,
        )
        assert result.exit_code == code, result.output
        errors = [line for line in result.output.splitlines() if line.startswith("Error")]
        assert len(errors) == 1 and message in errors[0], result.output
        assert dump(url) == before
        return result

    return invoke


@pytest.fixture
def fails(db_url: str) -> Fails:
    """:func:`checker` on each backend (PostgreSQL has its own limits: NUL, bigint, btree)."""
    seed(db_url)
    return checker(db_url)


@pytest.fixture(scope="module")
def seeded_sqlite(tmp_path_factory: pytest.TempPathFactory, sqlite_template: Path) -> Path:
    path = tmp_path_factory.mktemp("seeded") / "seeded.db"
    shutil.copy(sqlite_template, path)
    seed(f"sqlite:///{path}")
    return path


@pytest.fixture
def sqlite_fails(tmp_path: Path, seeded_sqlite: Path) -> Fails:
    """:func:`checker` on a seeded SQLite copy, for input refused before any database access
    (files, options)."""
    path = tmp_path / "toaster.db"
    shutil.copy(seeded_sqlite, path)
    return checker(f"sqlite:///{path}")


def write(tmp_path: Path, name: str, body: str | bytes) -> str:
    path = tmp_path / name
    if isinstance(body, bytes):
        path.write_bytes(body)
    else:
        path.write_text(body, encoding="utf-8")
    return str(path)


# ---------------------------------------------------------------------------- times
@pytest.mark.slow
@pytest.mark.parametrize(
    "args",
    [
        ("set-info", "FACT", "--subject", "MUG", "--property", "IsOn", "--target", "TABLE"),
        ("set-info", "EVENT", "--subject", "MUG", "--property", "Dropped"),
        ("set-info", "ENTITY", "--id", "CUP"),
        ("get-info", "FACT", "CURRENT"),
        ("beliefs", "show", "BOB"),
        ("tell", "BOB", "MUG", "IsOn", "TABLE"),
    ],
)
def test_times_outside_the_database_range(fails: Fails, args: tuple[str, ...]) -> None:
    """--at -1 hit a CHECK constraint, --at 999999999h an integer overflow; -1000000h (that
    long before now) is before the epoch."""
    for at in ("-1000000h", "999999999h", "9223372036854775808", "0001-01-01"):
        fails(*args, "--at", at, message=f"--at: time {at!r} = ")
        fails(
            *args,
            "--at",
            at,
            message="is out of range: times go from 0 "
            "(1970-01-01T00:00:00Z) to 2^63-1 ns (2262-04-11T23:47:16Z)",
        )


@pytest.mark.slow
@pytest.mark.parametrize("option", ["--from", "--to"])
def test_event_windows_outside_the_range(fails: Fails, tmp_path: Path, option: str) -> None:
    fails("get-info", "EVENT", option, "999999999h", message=f"{option}: time '999999999h'")
    fails("export", "events", str(tmp_path / "out.csv"), option, "-1", message="out of range")


def test_time_parser_bounds() -> None:
    assert parse_time("9223372036854775807") == 2**63 - 1
    assert parse_time("1.5s", start_ns=1) == 1_500_000_001
    assert parse_duration("0.1ns") == 0
    assert parse_duration("-292h") == -292 * 3600 * 10**9
    for text in ("1" + "0" * 400, "9" * 400 + ".5s", "1e3s", "nan"):
        with pytest.raises(ValueError, match="invalid time"):
            parse_time(text)


# ---------------------------------------------------------------------------- ids and text
@pytest.mark.slow
@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("a\x00b", "NUL character"),
        ("x\udcff", "not valid UTF-8"),
        ("x" * (MAX_ID_BYTES + 1), f"ids are at most {MAX_ID_BYTES} bytes of UTF-8"),
        (
            "💥" * 65,
            f"ids are at most {MAX_ID_BYTES} bytes of UTF-8 (256 ASCII characters), not 260",
        ),
        ("é" * 3000, f"ids are at most {MAX_ID_BYTES} bytes"),
    ],
)
def test_bad_ids(fails: Fails, value: str, message: str) -> None:
    """NUL (PostgreSQL refuses it in text), lone surrogates (undecodable argv bytes) and ids
    over the btree index row limit."""
    if "\x00" in value or "\udcff" in value:  # refused for every command, reads too
        fails("get-info", "FACT", "ALL", "--subject", value, message=message)
        fails("tolerance", value, "1", message=message)
    else:
        fails("set-info", "ENTITY", "--id", value, message=message)
        fails("set-info", "FACT", "--subject", "MUG", "--property", value, message=message)
        fails(
            "set-info", "PROPERTY", "--id", "MUG", "--key", "k", "--value", value, message="at most"
        )
    fails("set-info", "ENTITY", "--id", value, message=message)


def test_check_id_is_the_one_place() -> None:
    assert check_id("x" * MAX_ID_BYTES, "id") == "x" * MAX_ID_BYTES
    assert check_id("💥" * (MAX_ID_BYTES // 4), "id") == "💥" * 64
    for bad in ("", "  ", None, 5, "a\x00", "\ud800"):
        with pytest.raises(ValueError, match="invalid id"):
            check_id(bad, "id")


@pytest.mark.slow
def test_the_longest_ids_fit_every_index(db_url: str) -> None:
    """Ids of MAX_ID_BYTES of 4-byte characters, in the widest index row: a fact key (six ids)
    of a nested holder A>B>C>D at the deepest depth. PostgreSQL's btree holds 2704 bytes."""
    db = toaster.connect(db_url)
    try:
        st = db.store()
        people = ["".join(chr(0x1F300 + 64 * k + i) for i in range(64)) for k in range(4)]
        st.add_entity("R", "robot", is_self=True, t_ns=0)
        for person in people:
            st.add_entity(person, "human", t_ns=0)
        api.configure(db, depth=4, share_rows=False)  # every holder keeps its own keys
        big = ["".join(chr(0x10000 + 64 * k + i) for i in range(64)) for k in range(5)]
        here = [toaster.Fact(p, "IsInRoom", "ROOM") for p in [*people, big[0]]]
        st.sync_snapshot("t", "R", 1, here)
        st.sync_snapshot(
            "t",
            "R",
            2,
            [
                *here,
                toaster.Fact(
                    big[0],
                    big[1],
                    big[2],
                    sub_property=big[3],
                    subject_owner_id=big[4],
                    target_owner_id=people[0],
                ),
            ],
        )
        deepest = ">".join(people)
        assert deepest in api.holders(db)
        with db.transaction() as conn:
            keys = conn.execute(
                sa.text("SELECT count(*) FROM fact_keys WHERE agent_id = :a AND property = :p"),
                {"a": deepest, "p": big[1]},
            ).scalar_one()
        assert keys == 1
    finally:
        db.close()


# ---------------------------------------------------------------------------- numbers
@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--rate", "nan"), "invalid rate nan: give a finite number"),
        (("--rate", "0"), "--rate 0.0 must be a positive number of ticks per second"),
        (("--rate", "1e12"), "from 1e-06 to 10000"),
        (("--rate", "1e-300"), "from 1e-06 to 10000"),
        (("--until", "-1s"), "--until '-1s' must not be negative"),
    ],
)
def test_run_options(sqlite_fails: Fails, args: tuple[str, ...], message: str) -> None:
    sqlite_fails("run", str(EXAMPLES / "scenario_flat.yaml"), *args, message=message)


@pytest.mark.slow
def test_limits_and_numbers(fails: Fails) -> None:
    fails("get-info", "FACT", "--limit", "99999999999999999999", message="--limit", code=2)
    fails("get-info", "FACT", "--limit", "-1", message="--limit", code=2)
    fails(
        "set-info",
        "FACT",
        "--subject",
        "MUG",
        "--property",
        "P",
        "--num",
        "inf",
        message="invalid num inf",
    )
    fails("watch", "--timeout", "nan", message="invalid timeout nan")
    fails("entity", "pose", "MUG", "1e300", "0", message="within ±1e+06")


# ---------------------------------------------------------------------------- files
@pytest.mark.slow
def test_deeply_nested_yaml(sqlite_fails: Fails, tmp_path: Path) -> None:
    """RecursionError in the YAML and JSON parsers."""
    deep = "facts: " + "[" * 5000 + "]" * 5000 + "\n"
    sqlite_fails("set-info", "--file", write(tmp_path, "deep.yaml", deep), message="nested")
    sqlite_fails(
        "set-info",
        "--file",
        write(tmp_path, "deep.json", "[" * 5000 + "]" * 5000),
        message="nested",
    )
    sqlite_fails("tolerance", "Distance", "[" * 5000 + "]" * 5000, message="nested")
    sqlite_fails("area", "add", "x", "--spec", "[" * 5000 + "]" * 5000, message="nested")
    lines = ["l0: &l0 [" + ", ".join(["x"] * 10) + "]"]
    lines += [f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 10) + "]" for i in range(1, 8)]
    alias = "\n".join(lines) + "\n"  # a billion laughs: 10^8 values from 80 aliases
    sqlite_fails("set-info", "--file", write(tmp_path, "bomb.yaml", alias), message="values")


@pytest.mark.parametrize(
    "body",
    [
        b"\xff\xfe\x00t\x00_\x00s",
        b"t_s,id,x,y\n0,b\xe9b,1,2\n",
        b"t_s,id,x,y\n0,bob\x00,1,2\n",
        bytes(range(256)),
    ],
)
def test_binary_and_non_utf8_tracks(sqlite_fails: Fails, tmp_path: Path, body: bytes) -> None:
    sqlite_fails("run", write(tmp_path, "tracks.csv", body), message="tracks")


def test_tracks_with_nan_poses_write_nothing(sqlite_fails: Fails, tmp_path: Path) -> None:
    """A NaN pose half-way used to fail after half the run was committed."""
    rows = [f"{i / 10},bob,{i / 10},0" for i in range(40)] + ["4.0,bob,nan,0"]
    sqlite_fails(
        "run",
        write(tmp_path, "t.csv", "t_s,id,x,y\n" + "\n".join(rows)),
        message="t.csv line 42: x is 'nan', not a finite number",
    )
    rows[-1] = "1e40,bob,1,0"
    sqlite_fails(
        "run", write(tmp_path, "t.csv", "t_s,id,x,y\n" + "\n".join(rows)), message="t_s", code=1
    )
    jsonl = "\n".join(
        json.dumps(r)
        for r in ({"t_ns": 1, "id": "bob", "x": 0, "y": 0}, {"t_ns": 2, "id": [1], "x": 0, "y": 0})
    )
    sqlite_fails("run", write(tmp_path, "t.jsonl", jsonl), message="line 2: invalid id [1]")


def scenario(tmp_path: Path, **changes: object) -> str:
    doc = {
        "name": "s",
        "duration": "2s",
        "rate": 5,
        "entities": [
            {"id": "R", "kind": "robot", "self": True},
            {"id": "bob", "kind": "human"},
            {"id": "cup", "size": [0.1, 0.1, 0.1]},
        ],
    }
    doc.update(changes)
    return write(tmp_path, "s.json", json.dumps(doc))


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"start": 99999999999999999999}, "out of range"),
        ({"start": "2262-04-11T23:47:16Z", "duration": "10s"}, "the scenario's end"),
        ({"rate": float("nan")}, "rate nan"),
        ({"config": [1, 2]}, "'config' must map"),
        ({"config": {"monitored_agents": 5}}, "monitored_agents"),
        ({"config": {"agent_size": "big"}}, "agent_size"),
        ({"config": {"motion_max_gap": 1e300}}, "motion_max_gap"),
        ({"entities": [{"id": "cup", "size": "big"}]}, "size"),
        ({"entities": [{"id": "cup", "position": [1e308, 0]}]}, "within ±1e+06"),
        ({"entities": [{"id": "cup"}, {"id": "cup"}]}, "declared twice"),
        (
            {
                "entities": [{"id": "bob", "kind": "human"}, {"id": "cup"}],
                "timeline": [
                    {"at": "1s", "put_in_hand": "cup", "agent": "bob", "hand": "rightHand"}
                ],
            },
            "has no joint 'rightHand'",
        ),
        ({"areas": {"a": {"shape": "circle", "center": [0, "x"], "radius": 1}}}, "non-number"),
        (
            {"areas": {"a": {"shape": "polygon", "points": [[0, 0], [1, float("nan")], [1, 1]]}}},
            "nan",
        ),
    ],
)
def test_bad_scenarios(sqlite_fails: Fails, tmp_path: Path, changes: dict, message: str) -> None:
    """A huge start time, a size given as text, a config given as a list..."""
    sqlite_fails("run", scenario(tmp_path, **changes), message=message)


def test_non_utf8_scenario_and_config(sqlite_fails: Fails, tmp_path: Path) -> None:
    sqlite_fails(
        "run",
        write(tmp_path, "s.yaml", b"name: caf\xe9\nentities: []\n"),
        message="not UTF-8 text (byte 0xe9 on line 1)",
    )
    sqlite_fails(
        "run",
        scenario(tmp_path),
        "--config",
        write(tmp_path, "c.yaml", "- 1\n- 2\n"),
        message="must be a mapping",
    )


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        ({"facts": [{"agent": [1, 2], "subject": "MUG", "property": "P"}]}, "invalid agent [1, 2]"),
        ({"facts": [{"agent": {"x": 1}, "subject": "MUG", "property": "P"}]}, "invalid agent"),
        ({"facts": [{"subject": "MUG", "property": "P", "confidence": "high"}]}, "confidence"),
        ({"facts": [{"subject": "MUG", "property": "P", "target": ["TABLE"]}]}, "invalid target"),
        ({"events": [{"subject": "MUG", "property": "P", "at": 2**70}]}, "out of range"),
        ({"entities": [{"id": "X", "self": "maybe"}]}, "invalid self 'maybe'"),
        (
            {"ontology": [{"class": "a", "individual": "b", "instantiated": [1]}]},
            "invalid instantiated",
        ),
        ({"properties": [{"entity": "MUG", "key": "k", "value": {"a": 1}}]}, "give text"),
        (
            {
                "timeline": [
                    {"at": "1s", "facts": [{"subject": "MUG", "property": "P"}]},
                    {"at": "2s", "facts": "MUG"},
                ]
            },
            "timeline[1]: 'facts' must be a list",
        ),
    ],
)
def test_batch_rows_are_checked_before_any_write(
    sqlite_fails: Fails, tmp_path: Path, rows: dict, message: str
) -> None:
    """Odd agent fields and the like: the whole file is checked before its transaction."""
    doc = {"entities": [{"id": "NEW", "kind": "object"}], **rows}
    sqlite_fails("set-info", "--file", write(tmp_path, "b.json", json.dumps(doc)), message=message)


def test_bad_xml_seed(sqlite_fails: Fails, tmp_path: Path) -> None:
    sqlite_fails(
        "set-info",
        "--file",
        write(tmp_path, "s.xml", b"<a><agent id='x' type="),
        message="cannot read",
    )
    sqlite_fails(
        "set-info", "--file", write(tmp_path, "s.xml", b"<a>\xff</a>"), message="cannot read"
    )
    long = "x" * 300
    seed = f"<l><agent id='{long}' type='robot'/></l>"
    sqlite_fails(
        "set-info", "--file", write(tmp_path, "s.xml", seed), message="element 1: invalid id"
    )


@pytest.mark.parametrize(
    ("body", "message"),
    [(b"\xff\xfe\n", "not UTF-8 text"), (b"[" * 5000 + b"\n", "nested too deep")],
)
def test_bad_frames_file(sqlite_fails: Fails, tmp_path: Path, body: bytes, message: str) -> None:
    pytest.importorskip("rosbags")
    sqlite_fails("record", write(tmp_path, "f.jsonl", body), str(tmp_path / "out"), message=message)


@pytest.mark.slow
def test_belief_replay_writes_all_or_nothing(sqlite_fails: Fails, tmp_path: Path) -> None:
    doc = {
        "self": "ROBOT",
        "agents": ["SALLY"],
        "objects": ["BALL"],
        "steps": [{"t": 1, "rooms": {"SALLY": "ROOM"}}],
        "expect": [{"agent": "ANNE", "subject": "BALL", "property": "IsIn"}],
    }
    sqlite_fails(
        "beliefs",
        "replay",
        write(tmp_path, "b.json", json.dumps(doc)),
        message="the agent must be the self or one of the agents",
    )
    doc["expect"] = [{"agent": "SALLY", "about": "ROBOT", "subject": "BALL", "property": "IsIn"}]
    doc["settings"] = {"depth": 1}
    sqlite_fails("beliefs", "replay", write(tmp_path, "b.json", json.dumps(doc)), message="depth")


def test_hand_remove_of_a_free_object_writes_nothing(sqlite_fails: Fails) -> None:
    sqlite_fails("hand", "remove", "MUG", message="'MUG' is in no hand")


# ---------------------------------------------------------------------------- fixed elsewhere
def test_sql_param_without_value(sqlite_fails: Fails) -> None:
    """cli/execute.py: ``execute SQL ... --param b`` was a ValueError traceback."""
    sqlite_fails(
        "execute",
        "SQL",
        "SELECT :b",
        "--param",
        "b",
        message="--param 'b' takes NAME=VALUE",
        code=2,
    )


def test_unknown_revision(sqlite_fails: Fails) -> None:
    """db/migrate.py: ``db downgrade zzzz`` was alembic's CommandError traceback."""
    sqlite_fails("db", "downgrade", "zzzz", message="unknown revision 'zzzz'")
    sqlite_fails("db", "upgrade", "0011@", message="unknown revision '0011@'")


def test_relative_revision_past_the_head(sqlite_fails: Fails) -> None:
    sqlite_fails("db", "upgrade", "+1", message="+1")


@pytest.mark.parametrize("kind", ["facts", "events"])
def test_export_into_a_missing_folder_is_one_line(fails: Fails, tmp_path: Path, kind: str) -> None:
    """An output path whose folder does not exist: one line naming it and the fix."""
    missing = tmp_path / "no such folder" / "out.csv"
    fails("export", kind, str(missing), message="create its folder or give another path")
    assert not missing.parent.exists()
