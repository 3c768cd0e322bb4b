"""Belief holders: only the agents asked for (``--holders``, config ``belief_holders``)."""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa
from click.testing import CliRunner

import toaster
from tests.conftest import shared_data
from toaster.cli import cli
from toaster.errors import InvalidInputError
from toaster.producers import load_session

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "toaster" / "examples"


def zara01() -> Path:
    return shared_data("eth-ucy-opentraj", "UCY", "zara01", "obsmat.txt")


def run(db_url: str, path: Path, *args: str) -> str:
    done = CliRunner().invoke(cli, ["run", str(path), "--db", db_url, *args])
    assert done.exit_code == 0, done.output
    return done.output


def rows(db_url: str, sql: str) -> list[tuple]:
    db = toaster.connect(db_url)
    try:
        with db.transaction() as conn:
            return [tuple(r) for r in conn.execute(sa.text(sql))]
    finally:
        db.close()


def agents(db_url: str) -> dict[str, bool]:
    """Registered agents (not the "a>b" chains the belief rules add for second-order beliefs)."""
    return {a: bool(s) for a, s in rows(db_url, "SELECT id, is_self FROM agents") if ">" not in a}


def humans(db_url: str) -> set[str]:
    return {r[0] for r in rows(db_url, "SELECT id FROM entities WHERE kind = 'human'")}


@pytest.mark.slow
@pytest.mark.shared_data
def test_tracks_have_no_human_holders_by_default(db_url: str) -> None:
    run(db_url, zara01(), "--until", "5s")
    assert rows(db_url, "SELECT id, is_self FROM agents") in ([("toaster", True)], [("toaster", 1)])
    assert len(humans(db_url)) == 148  # still entities
    facts = rows(db_url, "SELECT count(*) FROM facts")[0][0]
    assert facts > 0


@pytest.mark.slow
@pytest.mark.shared_data
def test_holders_humans_makes_every_person_an_agent(db_url: str) -> None:
    run(db_url, zara01(), "--until", "5s", "--holders", "humans")
    held = agents(db_url)
    assert held.pop("toaster") is True
    assert set(held) == humans(db_url)
    assert len(held) == 148
    assert not any(held.values())


@pytest.mark.slow
@pytest.mark.shared_data
def test_holders_ids(db_url: str) -> None:
    run(db_url, zara01(), "--until", "5s", "--holders", "ped1, ped3")
    assert agents(db_url) == {"toaster": True, "ped1": False, "ped3": False}


@pytest.mark.slow
@pytest.mark.shared_data
def test_unknown_holder_is_refused_before_writing(db_url: str) -> None:
    done = CliRunner().invoke(
        cli, ["run", str(zara01()), "--db", db_url, "--holders", "ped1,ped9999"]
    )
    assert done.exit_code == 1
    lines = done.output.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("Error: belief holder 'ped9999' is not a human of obsmat.txt")
    assert rows(db_url, "SELECT count(*) FROM entities") == [(0,)]


@pytest.mark.slow
def test_scenario_keeps_its_humans_as_agents(db_url: str) -> None:
    run(db_url, EXAMPLES / "scenario_flat.yaml", "--until", "2s")
    assert agents(db_url) == {"pr2": True, "alice": False, "bob": False}


@pytest.mark.slow
def test_scenario_config_and_option_choose_holders(db_url: str, tmp_path: Path) -> None:
    text = (EXAMPLES / "scenario_simu_set.yaml").read_text()
    assert "\nconfig:" not in text
    path = tmp_path / "set.yaml"
    path.write_text(text + "\nconfig:\n  belief_holders: none\n")
    session = load_session(path)
    assert session.belief_holders == "none"
    run(db_url, path, "--until", "1s")
    held = agents(db_url)
    assert held.pop("PR2_ROBOT") is True
    assert held == {"Spencer": False}  # other robots stay agents
    assert humans(db_url)  # the humans are still entities
    assert load_session(path, holders="humans").belief_holders == "humans"


def test_holders_choices_are_checked(tmp_path: Path) -> None:
    flat = EXAMPLES / "scenario_flat.yaml"
    assert load_session(flat).belief_holders == "humans"
    assert load_session(flat, holders=["alice"]).belief_holders == ("alice",)
    assert load_session(flat, holders="None").belief_holders == "none"
    for bad, message in (
        (",", "no belief holders given"),
        ("mug", "'mug' is not a human"),
        (["alice", 3], "give none, humans or a list of ids"),
    ):
        with pytest.raises(InvalidInputError, match=message) as info:
            load_session(flat, holders=bad)
        assert "\n" not in str(info.value)
    csv = tmp_path / "t.csv"
    csv.write_text("t_s,id,x,y\n0,bob,0,0\n")
    assert load_session(csv).belief_holders == "none"
    assert load_session(csv, holders="bob").belief_holders == ("bob",)


@pytest.mark.slow
def test_fps_with_a_scenario_is_one_line_error(db_url: str) -> None:
    done = CliRunner().invoke(
        cli, ["run", str(EXAMPLES / "scenario_flat.yaml"), "--db", db_url, "--fps", "25"]
    )
    assert done.exit_code == 1
    assert done.output.strip().splitlines() == [
        "Error: --fps is for obsmat .txt recordings (frame numbers): scenario_flat.yaml gives "
        "its own times; use --rate for ticks per second"
    ]
