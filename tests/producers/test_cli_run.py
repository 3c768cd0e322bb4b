from pathlib import Path

import pytest
from click.testing import CliRunner

from toaster.cli import cli
from toaster.cli.run import area, run

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "toaster" / "examples"
DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "eth-ucy-opentraj"
for command in (run, area):
    if command.name not in cli.commands:
        cli.add_command(command)


def dump(url):
    from sqlalchemy import create_engine, text

    engine = create_engine(url)
    with engine.connect() as conn:
        tables = [
            r[0]
            for r in conn.execute(
                text(
                    "SELECT name FROM sqlite_master WHERE type='table' AND (name LIKE '%fact%' "
                    "OR name LIKE '%event%')"
                )
            )
        ]
        out = {}
        for t in tables:  # the store's last column is its wall-clock write stamp: not compared
            rows = conn.execute(text(f"SELECT * FROM {t}"))
            cols = list(rows.keys())
            keep = [
                i
                for i, k in enumerate(cols)
                if not (k.startswith("recorded") or k.endswith("wall_ns"))
            ]
            out[t] = sorted(tuple(r[i] for i in keep) for r in rows)
        return out


def test_run_twice_into_fresh_databases_gives_same_facts(tmp_path):
    out = []
    for k in range(2):
        url = f"sqlite:///{tmp_path}/r{k}.db"
        res = CliRunner().invoke(
            cli, ["run", str(EXAMPLES / "scenario_flat.yaml"), "--db", url, "--until", "20s"]
        )
        assert res.exit_code == 0, res.output
        assert "ticks" in res.output
        assert "events" in res.output
        out.append(dump(url))
    assert out[0] == out[1]
    assert any(out[0].values())


def test_area_commands(tmp_path):
    url = f"sqlite:///{tmp_path}/a.db"
    r = CliRunner()
    res = r.invoke(
        cli,
        [
            "--db",
            url,
            "area",
            "add",
            "desk",
            "--spec",
            '{"shape": "circle", "center": [1, 2], "radius": 1}',
        ],
    )
    assert res.exit_code == 0, res.output
    assert "desk" in r.invoke(cli, ["--db", url, "area", "list"]).output
    assert '"radius": 1.0' in r.invoke(cli, ["--db", url, "area", "show", "desk"]).output
    bad = r.invoke(cli, ["--db", url, "area", "add", "x", "--spec", '{"shape": "star"}'])
    assert bad.exit_code == 1
    assert "unknown shape" in bad.output
    assert r.invoke(cli, ["--db", url, "area", "remove", "desk"]).exit_code == 0
    assert r.invoke(cli, ["--db", url, "area", "remove", "desk"]).exit_code == 1


@pytest.mark.skipif(not DATA.is_dir(), reason=f"shared data not found at {DATA}")
def test_run_obsmat_into_database(tmp_path):
    res = CliRunner().invoke(
        cli,
        [
            "run",
            str(DATA / "UCY/zara01/obsmat.txt"),
            "--db",
            f"sqlite:///{tmp_path}/z.db",
            "--until",
            "60s",
        ],
    )
    assert res.exit_code == 0, res.output
    print(res.output)


def test_a_crowd_recording_registers_its_people_without_views(tmp_path):
    """A recording's thousands of people become agents in one bulk registration, without
    per-agent views (DDL); `db check` says so and `db views` makes them on demand."""
    import json

    tracks = tmp_path / "crowd.jsonl"
    tracks.write_text(
        "".join(
            json.dumps({"t_s": k * 0.1, "id": f"p{i}", "x": i, "y": k}) + "\n"
            for i in range(300)
            for k in range(2)
        )
    )
    url = f"sqlite:///{tmp_path}/crowd.db"
    res = CliRunner().invoke(cli, ["--db", url, "run", str(tracks), "--holders", "humans"])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(cli, ["--db", url, "db", "check"])
    assert res.exit_code == 0, res.output
    assert "300 agent(s) have no per-agent views" in res.output
    res = CliRunner().invoke(cli, ["--db", url, "db", "views", "p7"])
    assert res.exit_code == 0 and "created the views of 1 agent(s)" in res.output
    res = CliRunner().invoke(
        cli, ["--db", url, "execute", "SQL", 'SELECT count(*) FROM "fact_table_p7"']
    )
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(cli, ["--db", url, "db", "views"])
    assert "created the views of 299 agent(s)" in res.output  # p7 and the robot had theirs
    res = CliRunner().invoke(cli, ["--db", url, "db", "check"])
    assert res.exit_code == 0 and "no per-agent views" not in res.output
