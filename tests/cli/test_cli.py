"""The command line: thin over the library, one-line errors, JSON/CSV for scripts."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.conftest import shared_data
from toaster.cli import cli

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


@pytest.fixture
def run(db_url: str):
    """Invoke ``toaster --db URL ...`` and return the result."""
    runner = CliRunner()

    def invoke(*args: str, ok: bool = True, input: str | None = None):
        result = runner.invoke(cli, ["--db", db_url, *args], input=input)
        if ok:
            assert result.exit_code == 0, result.output
        return result

    return invoke


@pytest.fixture
def seeded(run):
    """A robot (self), a human and two objects."""
    run("set-info", "ENTITY", "--id", "PR2", "--type", "robot", "--self")
    run("set-info", "ENTITY", "--id", "BOB", "--type", "human")
    for name in ("MUG", "TABLE"):
        run("set-info", "ENTITY", "--id", name, "--type", "object")
    return run


def test_fact_add_value_and_remove(seeded) -> None:
    """set-info FACT add / remove and get-info FACT VALUE / CURRENT / OLD, as of a time."""
    run = seeded
    run(
        "set-info",
        "FACT",
        "--subject",
        "MUG",
        "--property",
        "IsOn",
        "--target",
        "TABLE",
        "--at",
        "2026-01-01T00:00:00Z",
        "--confidence",
        "0.7",
    )
    run(
        "set-info",
        "FACT",
        "--remove",
        "--subject",
        "MUG",
        "--property",
        "IsOn",
        "--target",
        "NULL",
        "--at",
        "2026-01-01T00:01:00Z",
    )
    value = run(
        "get-info",
        "FACT",
        "VALUE",
        "--subject",
        "MUG",
        "--property",
        "IsOn",
        "--target",
        "TABLE",
        "--at",
        "2026-01-01T00:00:30Z",
        "--json",
    )
    row = json.loads(value.output)
    assert (row["agent_id"], row["confidence"], row["valid_to_ns"]) == (
        "PR2",
        0.7,
        1767225660000000000,
    )
    now = run(
        "get-info", "FACT", "VALUE", "--subject", "MUG", "--property", "IsOn", "--target", "TABLE"
    )
    assert "does not hold" in now.output
    old = run("get-info", "FACT", "OLD", "--agent", "PR2", "--csv")
    rows = list(csv.DictReader(io.StringIO(old.output)))
    assert [(r["subject_id"], r["valid_from_ns"]) for r in rows] == [("MUG", "1767225600000000000")]
    table = run("get-info", "FACT", "ALL", "--agent", "PR2")
    assert "2026-01-01 00:01:00Z" in table.output  # times shown readably


def test_events_ontology_property_agent(seeded) -> None:
    """EVENT, ONTOLOGY (LEAVE), PROPERTY and AGENT round trips."""
    run = seeded
    run(
        "set-info",
        "EVENT",
        "--subject",
        "BOB",
        "--property",
        "PickUp",
        "--target",
        "MUG",
        "--at",
        "5s",
    )
    events = [json.loads(line) for line in run("get-info", "EVENT", "--json").output.splitlines()]
    assert [(e["kind"], e["stamp_ns"]) for e in events] == [("event", 5_000_000_000)]
    run("set-info", "ONTOLOGY", "--class", "container", "--individual", "mug")
    run("set-info", "ONTOLOGY", "--class", "mug", "--individual", "MUG", "--instantiated")
    leave = run("get-info", "ONTOLOGY", "LEAVE", "--class", "container", "--json")
    assert [json.loads(x)["individual"] for x in leave.output.splitlines()] == ["MUG"]
    run("set-info", "PROPERTY", "--id", "MUG", "--key", "color", "--value", "red")
    prop = run("get-info", "PROPERTY", "VALUE", "--id", "MUG", "--csv")
    assert prop.output.splitlines() == ["entity_id,key,value", "MUG,color,red"]
    agents = run("get-info", "AGENT", "--json").output.splitlines()
    assert {json.loads(a)["id"]: json.loads(a)["is_self"] for a in agents} == {
        "PR2": True,
        "BOB": False,
    }


def test_execute_sql_read_only_and_empty(seeded) -> None:
    """execute SQL refuses writes without --write; EMPTY clears an agent's beliefs."""
    run = seeded
    run("set-info", "FACT", "--subject", "MUG", "--property", "IsOn", "--target", "TABLE")
    refused = run("execute", "SQL", "DELETE FROM facts", ok=False)
    assert refused.exit_code == 1 and "--write" in refused.output
    assert "Traceback" not in refused.output
    counted = run("execute", "SQL", 'SELECT count(*) AS n FROM "fact_table_PR2"', "--csv")
    assert counted.output.splitlines() == ["n", "1"]
    assert (
        run(
            "execute", "ARE_IN_TABLE", "--subject", "MUG", "--property", "IsOn", "--target", "NULL"
        ).output.strip()
        == "true"
    )
    run("execute", "EMPTY", "AGENT", "--agent", "PR2", "--yes")
    absent = run("execute", "ARE_IN_TABLE", "--subject", "MUG", "--property", "IsOn", ok=False)
    assert absent.exit_code == 1 and absent.output.strip() == "false"
    run("execute", "SQL", "DELETE FROM properties", "--write")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ("set-info", "FACT", "--agent", "SALLY", "--subject", "MUG", "--property", "IsOn"),
            "unknown agent 'SALLY'",
        ),
        (("set-info", "FACT", "--subject", "CUP", "--property", "IsOn"), "unknown entity 'CUP'"),
        (
            ("set-info", "FACT", "--subject", "MUG", "--property", "IsOn", "--confidence", "nan"),
            "invalid confidence nan",
        ),
        (
            ("set-info", "FACT", "--subject", "MUG", "--property", "IsOn", "--observability", "2"),
            "invalid observability 2.0",
        ),
        (("set-info", "ENTITY", "--id", " "), "invalid entity id ' '"),
        (("get-info", "FACT", "CURRENT", "--at", "yesterday"), "invalid time 'yesterday'"),
        (("get-info", "FACT", "CURRENT", "--agent", "NOBODY"), "unknown agent 'NOBODY'"),
    ],
)
def test_bad_input_is_one_line(seeded, args: tuple[str, ...], message: str) -> None:
    """Each user mistake: exit code != 0, one line naming the value, nothing written."""
    result = seeded(*args, ok=False)
    assert result.exit_code != 0
    assert message in result.output, result.output
    assert "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    facts = seeded("execute", "SQL", "SELECT count(*) FROM facts", "--csv").output
    assert facts.splitlines()[1] == "0"


def test_batch_file_and_xml_seed(run, tmp_path: Path) -> None:
    """set-info --file takes the original's XML seeds and a JSON batch."""
    folder = shared_data("toaster-laas", "database_manager", "database")
    run("set-info", "--file", str(folder / "id_list.xml"), "--file", str(folder / "ontology.xml"))
    batch = tmp_path / "facts.json"
    batch.write_text(
        json.dumps(
            {
                "facts": [
                    {"subject": "RED_CUBE", "property": "IsOn", "target": "TABLE_4", "at": "1s"}
                ]
            }
        )
    )
    run("set-info", "--file", str(batch))
    current = run("get-info", "FACT", "CURRENT", "--json").output.splitlines()
    assert [(json.loads(x)["agent_id"], json.loads(x)["subject_id"]) for x in current] == [
        ("PR2_ROBOT", "RED_CUBE")
    ]


def test_db_commands(run) -> None:
    """db current / check / upgrade report the revision."""
    assert "database:" in run("db", "current").output
    run("db", "check")
    run("db", "upgrade")


def test_wrong_revision_names_the_fix(tmp_path: Path) -> None:
    """A database behind the code: get-info says to run toaster db upgrade."""
    from toaster.db import migrate
    from toaster.db.engine import make_engine

    if migrate.head_revision() == "0001":
        pytest.skip("only one revision exists")
    url = f"sqlite:///{tmp_path / 'old.db'}"
    engine = make_engine(url)
    migrate.upgrade(engine, "0001")
    engine.dispose()
    result = CliRunner().invoke(cli, ["--db", url, "get-info", "AGENT"])
    assert result.exit_code == 1
    assert "run `toaster db upgrade --db" in result.output
    assert CliRunner().invoke(cli, ["--db", url, "db", "upgrade"]).exit_code == 0
    assert CliRunner().invoke(cli, ["--db", url, "get-info", "AGENT"]).exit_code == 0
