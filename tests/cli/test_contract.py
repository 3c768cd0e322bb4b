"""One CLI contract (issue 15 item 4): ``--db`` the same way on every command, listings with
``--limit`` / ``--json`` / ``--csv`` / tab-separated lines when piped, every key column in
tables, optional extras checked before any work, and docs/cli.md generated from the commands.

Every command of ``toaster`` is classified below as a listing (with an invocation that lists
rows) or not (with the reason): a new command that is neither fails
:func:`test_every_command_is_classified`.
"""

from __future__ import annotations

import csv
import io
import json
import os
import pty
import re
import subprocess
import sys
import threading
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import click
import pytest
from click.testing import CliRunner, Result

import toaster
from tests.conftest import BACKENDS, pg_schema
from toaster.cli import cli
from toaster.cli.context import DB_HELP
from toaster.db import migrate
from toaster.db.engine import make_engine
from toaster.model import Fact

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "src" / "toaster" / "examples"
S = 1_000_000_000
BOX_CHARS = re.compile("[\u2500-\u257f]")  # rich's box drawing

#: listing command -> invocations that each list at least one row of the seeded database
LISTINGS: dict[str, list[list[str]]] = {
    "get-info": [
        ["FACT"],
        ["FACT", "CURRENT"],
        ["FACT", "OLD"],
        ["FACT", "CURRENT", "--at", "4s"],
        [
            "FACT",
            "VALUE",
            "--agent",
            "ROBOT",
            "--subject",
            "MARBLE",
            "--property",
            "IsIn",
            "--target",
            "BOX",
        ],
        ["EVENT"],
        ["ONTOLOGY"],
        ["ONTOLOGY", "LEAVE", "--class", "container"],
        ["ID"],
        ["ENTITY"],
        ["AGENT"],
        ["PROPERTY"],
    ],
    "execute": [["SQL", "SELECT id, kind FROM entities"], ["PRINT", "AGENT", "--agent", "ROBOT"]],
    "beliefs show": [["SALLY"], ["ANNE", "--about", "SALLY", "--at", "4s"]],
    "beliefs value": [["SALLY", "--subject", "MARBLE", "--property", "IsIn", "--target", "BOX"]],
    "beliefs diff": [["SALLY", "--at", "4s"]],
    "beliefs history": [["--subject", "MARBLE", "--property", "IsIn"]],
    "beliefs holders": [[]],
    "area list": [[]],
    "stream": [[]],
    "tolerance": [[]],
    "watch": [["--property", "IsMoving", "--timeout", "20", "--limit", "2"]],
}
#: every other command -> why it prints no rows
NOT_LISTINGS = {
    "area add": "writes",
    "area clear": "writes",
    "area remove": "writes",
    "area show": "one area's spec as JSON",
    "beliefs config": "settings as JSON",
    "beliefs replay": "writes; reports expectations",
    "db check": "a verdict",
    "db current": "two revisions",
    "db downgrade": "schema",
    "db maintain": "maintenance",
    "db upgrade": "schema",
    "db views": "writes views",
    "demo": "a guided tour",
    "entity add": "writes",
    "entity pose": "writes",
    "entity remove": "writes",
    "export": "writes a file",
    "hand put": "writes",
    "hand remove": "writes",
    "monitor add": "writes",
    "monitor all": "writes",
    "monitor clear": "writes",
    "monitor remove": "writes",
    "monitor list": "a state summary, the same as monitor add/remove print",
    "plot-facts": "writes a file",
    "pointing": "a running node's answer",
    "record": "writes a bag",
    "relative-position": "a running node's answer (JSON)",
    "relpos": "one position",
    "ros1 env": "shell exports",
    "run": "writes; a run report",
    "serve": "a live node",
    "set-info": "writes",
    "tell": "writes",
}


def commands(group: click.Group = cli, prefix: str = "") -> Iterator[tuple[str, click.Command]]:
    """Every command and group below ``group``, by path (``beliefs show``)."""
    for name, command in sorted(group.commands.items()):
        path = f"{prefix}{name}"
        yield path, command
        if isinstance(command, click.Group):
            yield from commands(command, path + " ")


LEAVES = [path for path, command in commands() if not isinstance(command, click.Group)]


# ----------------------------------------------------------------------------- the databases
def seed(url: str) -> None:
    """Sally-Anne replayed (agents, holders, beliefs, memory, events), two facts that differ
    only by sub-property, ontology, properties, areas and streams."""
    from toaster.beliefs.scenario import replay_and_check
    from toaster.node import control

    db = toaster.connect(url)
    try:
        _, failures = replay_and_check(db, EXAMPLES / "beliefs_sally_anne.yaml")
        assert not failures
        store = db.store()
        for sub in ("2D", "3D"):
            store.assert_fact(
                "ROBOT", Fact("MARBLE", "IsNear", "BASKET", sub_property=sub), t_ns=10 * S
            )
        store.add_ontology("container", "box")
        store.add_ontology("box", "BOX", True)
        store.add_ontology("container", "BASKET", True)
        store.set_property("BOX", "color", "red")
        store.set_property("BASKET", "color", "brown")
        for name, center in (("kitchen", [0, 0]), ("hall", [5, 0])):
            store.put_area(
                name, {"shape": "circle", "center": center, "radius": 2, "area_type": "room"}, ""
            )
        control.set_stream(db, "pdg", False)
        control.set_stream(db, "mocap", True)
    finally:
        db.close()


@pytest.fixture(scope="module", params=BACKENDS)
def seeded(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[str]:
    """The URL of a seeded database (:func:`seed`) on each backend, shared by the module's
    read-only tests."""
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path_factory.mktemp('contract') / 'seeded.db'}"
        seed(url)
        yield url
        return
    with pg_schema(migrated=True) as url:
        seed(url)
        yield url


def invoke(args: list[str], *, env: dict[str, str | None] | None = None) -> Result:
    result = CliRunner().invoke(cli, args, env=env)
    assert result.exit_code == 0, (args, result.output, result.exception)
    return result


class Writer:
    """Another writer changing MARBLE IsMoving every 0.1 s while a command runs (watch sees
    only what is committed after it starts)."""

    def __init__(self, url: str) -> None:
        self.url, self.stop = url, threading.Event()
        self.thread = threading.Thread(target=self._write)

    def _write(self) -> None:
        db = toaster.connect(self.url)
        try:
            store = db.store()
            while not self.stop.wait(0.1):  # (now: every writer's stamps go forward)
                store.assert_fact("ROBOT", Fact("MARBLE", "IsMoving", "", f"v{uuid.uuid4()}"))
        finally:
            db.close()

    def __enter__(self) -> Writer:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()


def listing(url: str, path: str, args: list[str], *extra: str) -> str:
    """Stdout of ``toaster PATH ARGS... EXTRA... --db URL`` (piped, as CliRunner's is)."""
    argv = [*path.split(), *args, *extra, "--db", url]
    if path != "watch":
        return invoke(argv).stdout
    with Writer(url):
        return invoke(argv).stdout


def data_lines(text: str) -> list[str]:
    """Lines of a listing without the table titles (``# fact_table_ROBOT``)."""
    return [line for line in text.splitlines() if not line.startswith("# ")]


# ----------------------------------------------------------------------------- classification
def test_every_command_is_classified() -> None:
    """A new command must say whether it lists rows (and then get the listing options)."""
    assert set(LISTINGS).isdisjoint(NOT_LISTINGS)
    assert set(LEAVES) == set(LISTINGS) | set(NOT_LISTINGS)


@pytest.mark.parametrize("path", LEAVES)
def test_listing_options_on_exactly_the_listings(path: str) -> None:
    command = dict(commands())[path]
    options = {opt for param in command.params for opt in getattr(param, "opts", [])}
    has = {"--limit", "--json", "--csv"} <= options
    assert has == (path in LISTINGS), path


@pytest.mark.slow
@pytest.mark.parametrize(
    ("path", "args"),
    [(path, args) for path, runs in LISTINGS.items() for args in runs],
    ids=lambda x: x if isinstance(x, str) else " ".join(x),
)
def test_listing_formats_and_limit(seeded: str, path: str, args: list[str]) -> None:
    """--json (every field), --csv (the same rows and fields), piped: tab-separated lines
    under one header, no box drawing; --limit N-1 gives N-1 rows."""
    objects = [json.loads(line) for line in listing(seeded, path, args, "--json").splitlines()]
    assert objects, f"{path} {args} lists no row: the seeded database should give some"
    fields = [key for key in objects[0] if key != "table"]
    rows = list(
        csv.reader(io.StringIO("\n".join(data_lines(listing(seeded, path, args, "--csv")))))
    )
    assert rows[0] == fields
    assert len(rows) - 1 == len(objects)
    piped = listing(seeded, path, args)
    assert not BOX_CHARS.search(piped), piped
    lines = [line.split("\t") for line in data_lines(piped)]
    assert len(lines) - 1 == len(objects)
    assert len(lines[0]) > 1 or fields == ["holder"]
    assert {len(line) for line in lines} == {len(lines[0])}
    limited = listing(seeded, path, args, "--limit", str(len(objects) - 1), "--json")
    assert len(limited.splitlines()) == len(objects) - 1


# ----------------------------------------------------------------------------- limits, keys
def test_limit_works_with_at(seeded: str) -> None:
    """--limit with --at (beliefs as of a time) was ignored."""
    every = listing(seeded, "get-info", ["FACT", "CURRENT", "--at", "4s"], "--json")
    assert len(every.splitlines()) > 2
    two = listing(seeded, "get-info", ["FACT", "CURRENT", "--at", "4s"], "--limit", "2", "--json")
    assert two.splitlines() == every.splitlines()[:2]
    one = listing(seeded, "beliefs show", ["ANNE", "--at", "4s"], "--limit", "1", "--json")
    assert len(one.splitlines()) == 1


def _near_rows(lines: list[list[str]]) -> list[dict[str, str]]:
    header = lines[0]
    return [dict(zip(header, line, strict=True)) for line in lines[1:] if "IsNear" in line]


def test_piped_rows_show_their_whole_key(seeded: str) -> None:
    """Two facts that differ only by sub-property are told apart in the listing."""
    piped = listing(seeded, "get-info", ["FACT", "CURRENT", "--agent", "ROBOT"])
    lines = [line.split("\t") for line in piped.splitlines()]
    assert {
        "agent",
        "subject",
        "subject_owner",
        "property",
        "sub_property",
        "target",
        "target_owner",
    } <= set(lines[0])
    near = _near_rows(lines)
    assert sorted(row["sub_property"] for row in near) == ["2D", "3D"]


@pytest.mark.slow
def test_terminal_table_shows_sub_property(seeded: str) -> None:
    """On a terminal (a pseudo-terminal here) the table is drawn, with the sub-property
    column when a row has one and without the empty owner columns."""
    master, slave = pty.openpty()
    env = {**os.environ, "COLUMNS": "250", "TERM": "xterm"}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "toaster",
            "get-info",
            "FACT",
            "CURRENT",
            "--agent",
            "ROBOT",
            "--subject",
            "MARBLE",
            "--db",
            seeded,
        ],
        stdout=slave,
        stderr=subprocess.PIPE,
        env=env,
    )
    os.close(slave)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(master)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    table = b"".join(chunks).decode()
    assert BOX_CHARS.search(table)
    header = next(line for line in table.splitlines() if "subject" in line)
    assert "sub_property" in header and "target_owner" not in header
    near = [line for line in table.splitlines() if "IsNear" in line]
    assert len(near) == 2 and {"2D", "3D"} == {
        w for line in near for w in line.split() if w in ("2D", "3D")
    }


# ----------------------------------------------------------------------------- --db
def test_db_is_declared_once() -> None:
    """One declaration (toaster.cli.context): no other module of the CLI spells --db."""
    spelled = [
        path.name
        for path in (ROOT / "src" / "toaster" / "cli").glob("*.py")
        if '"--db"' in path.read_text() and path.name != "context.py"
    ]
    assert spelled == []
    for path, command in [("toaster", cli), *commands()]:
        option = next((p for p in command.params if p.name == "db"), None)
        assert option is not None and option.help == DB_HELP, path


@pytest.mark.parametrize("path", [path for path, _ in commands()])
def test_db_is_accepted_before_and_after_every_command(path: str, tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'x.db'}"
    for argv in (["--db", url, *path.split(), "--help"], [*path.split(), "--db", url, "--help"]):
        result = CliRunner().invoke(cli, argv)
        assert result.exit_code == 0, (argv, result.output)


#: commands run with --db after their name while $TOASTER_DB names a decoy; then a check
#: that they used the flag's database
FLAG_OVER_ENV: list[tuple[Callable[[Path], list[str]], Callable[[Any, str], bool]]] = [
    (
        lambda _: ["set-info", "ENTITY", "--id", "CUP"],
        lambda db, _out: any(e.id == "CUP" for e in _q().entities(db)),
    ),
    (lambda _: ["get-info", "AGENT", "--json"], lambda _db, out: '"SALLY"' in out),
    (
        lambda p: ["export", "history", str(p / "h.csv")],
        lambda _db, out: re.search(r"wrote [1-9]\d* history rows", out) is not None,
    ),
    (
        lambda p: ["plot-facts", str(p / "p.csv"), "-s", "MARBLE"],
        lambda _db, out: "wrote" in out and "MARBLE" in (Path(out.split()[1]).read_text()),
    ),
    (
        lambda _: [
            "area",
            "add",
            "desk",
            "--spec",
            '{"shape": "circle", "center": [1, 2], "radius": 1}',
        ],
        lambda db, _out: "desk" in db.store().areas(),
    ),
    (
        lambda _: ["tolerance", "Distance", "0.25"],
        lambda db, _out: db.store().tolerances()["Distance"].value == 0.25,
    ),
    (lambda _: ["beliefs", "holders"], lambda _db, out: "ANNE>SALLY" in out),
    (lambda _: ["db", "current"], lambda _db, out: migrate.head_revision() in out),
    (
        lambda _: ["execute", "SQL", "SELECT count(*) AS n FROM holders", "--csv"],
        lambda _db, out: out.splitlines()[1] != "0",
    ),
    (
        lambda _: ["run", str(EXAMPLES / "scenario_flat.yaml"), "--until", "1s"],
        lambda db, _out: len(_q().history(db, "pr2")) > 0,
    ),
]


def _q() -> Any:
    from toaster import queries

    return queries


@pytest.mark.slow
def test_flag_wins_over_environment(db_url: str, tmp_path: Path) -> None:
    """$TOASTER_DB names a decoy: each command given --db (after its name, or before)
    uses the flag's database and never creates the decoy."""
    decoy = tmp_path / "decoy.db"
    seed(db_url)
    env = {"TOASTER_DB": f"sqlite:///{decoy}"}
    for k, (make, used) in enumerate(FLAG_OVER_ENV):
        argv = make(tmp_path)
        argv = [*argv, "--db", db_url] if k % 2 == 0 else ["--db", db_url, *argv]
        result = invoke(argv, env=env)
        assert not decoy.exists(), argv
        with toaster.connect(db_url) as db:
            assert used(db, result.output), (argv, result.output)


def test_environment_without_flag_and_conflicting_flags(seeded: str, tmp_path: Path) -> None:
    """Without --db, $TOASTER_DB is used; two different --db are refused in one line."""
    out = invoke(["get-info", "AGENT", "--json"], env={"TOASTER_DB": seeded}).stdout
    assert '"SALLY"' in out
    other = f"sqlite:///{tmp_path / 'other.db'}"
    result = CliRunner().invoke(cli, ["--db", seeded, "get-info", "AGENT", "--db", other])
    assert result.exit_code == 2
    assert "--db given twice" in result.output
    assert not (tmp_path / "other.db").exists()
    same = invoke(["--db", seeded, "get-info", "AGENT", "--db", seeded, "--json"]).stdout
    assert same == out


# ----------------------------------------------------------------------------- extras
BLOCKED = [
    (
        "rosbags",
        "rosbag",
        lambda p: [
            "run",
            str(EXAMPLES / "scenario_flat.yaml"),
            "--until",
            "1s",
            "--record",
            str(p / "rec"),
        ],
    ),
    ("rosbags", "rosbag", lambda p: ["record", str(p / "frames.jsonl"), str(p / "rec")]),
    ("cyclonedds", "ros2", lambda p: ["serve", "--ros2", "--seconds", "0"]),
    ("foxglove", "foxglove", lambda p: ["serve", "--foxglove", "0", "--seconds", "1"]),
    (
        "foxglove",
        "foxglove",
        lambda p: [
            "run",
            str(EXAMPLES / "scenario_flat.yaml"),
            "--record",
            str(p / "rec.mcap"),
            "--record-format",
            "foxglove",
        ],
    ),
    ("cyclonedds", "ros2", lambda p: ["run", str(EXAMPLES / "scenario_flat.yaml"), "--ros2"]),
    ("foxglove", "foxglove", lambda p: ["run", str(EXAMPLES / "scenario_flat.yaml"), "--foxglove"]),
    ("matplotlib", "plot", lambda p: ["plot-facts", str(p / "out.png")]),
    ("pyarrow", "export", lambda p: ["export", "history", str(p / "out.parquet")]),
]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("module", "extra", "make"), BLOCKED, ids=[b[2](Path("x"))[0] for b in BLOCKED]
)
def test_missing_extra_fails_before_any_work(
    empty_url: str, tmp_path: Path, module: str, extra: str, make: Callable[[Path], list[str]]
) -> None:
    """The extra's package cannot be imported (blocked in sys.modules, as when it is not
    installed): one line naming pip install 'toaster[EXTRA]', the database untouched (not even
    created), no output written."""
    (tmp_path / "frames.jsonl").write_text(json.dumps({"t_ns": 0, "entities": []}) + "\n")
    argv = [*make(tmp_path), "--db", empty_url]
    code = (
        f"import sys; sys.modules[{module!r}] = None; from toaster.cli import main; "
        f"sys.argv = ['toaster', *{argv!r}]; main()"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), done.stderr
    assert f"pip install 'toaster[{extra}]'" in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames.jsonl"]
    engine = make_engine(empty_url)
    try:
        from sqlalchemy import inspect

        assert inspect(engine).get_table_names() == []
    finally:
        engine.dispose()


# ----------------------------------------------------------------------------- reference
@pytest.mark.slow
def test_cli_reference_is_up_to_date() -> None:
    """docs/cli.md is what `python -m toaster.cli.reference docs/cli.md` writes now (run as
    that command, in a fresh interpreter: click caches each command's help option the first
    time it is used, so a test that invoked a command on its own, outside the group, would
    have it render `--help` without `-h`)."""
    rendered = subprocess.run(
        [sys.executable, "-m", "toaster.cli.reference"],
        check=True,
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    written = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    assert written == rendered, (
        "docs/cli.md is out of date: run `python -m toaster.cli.reference docs/cli.md`"
    )
    for path, _ in commands():
        assert f"## toaster {path}\n" in written
