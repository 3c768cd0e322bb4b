"""Beyond one server, on real servers: a hot standby answers toaster's reads exactly as its
primary does (and refuses writes in one line), and logical replication copies a site's memory
into an archive, one database or schema per site (docs/databases.md, "Beyond one server").

Every test starts its own throw-away clusters with this machine's server binaries
(:mod:`tests.db.clusters`); the shared server at 127.0.0.1:5432 is never reconfigured (one
test takes a schema of it, as every PostgreSQL test does). Replication
is waited for by its positions (the standby's replay LSN, the subscription's confirmed LSN)
with a generous time-out, never a wall-clock window.
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import pytest
from click.testing import CliRunner

import toaster
from tests.conftest import pg_schema
from tests.db.clusters import Cluster, clusters
from toaster import queries
from toaster.cli import cli
from toaster.db import schema
from toaster.model import Fact

pytestmark = pytest.mark.postgresql

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs" / "databases.md"
STORY = ROOT / "src" / "toaster" / "examples" / "beliefs_sally_anne.yaml"
SECOND = 1_000_000_000
#: The tables an archive does not take, and why (every other table of the schema is published).
NOT_PUBLISHED = {
    "alembic_version": "each database has its own revision, migrated by toaster",
    "store_state": "the writers' clock and caches: one seeded row per database",
    "control_commands": "one-shot requests to the site's running node",
    "fact_inbox": "a write surface: its rows are applied and not kept",
    "rule_writer": "SQLite's writer role",
    "belief_runs": "inserting a row runs the belief rule: rows are not kept",
    "belief_steps": "SQLite's blocks of a run",
    "belief_groups": "the rule's grouping of holders, for its next run",
    "belief_perceived": "the rule's kept perception, for its next runs (store_state says whose)",
    "belief_settled": "the rule's settled keys, kept with its perception",
    **dict.fromkeys(
        ("belief_changed", "belief_focus", "belief_seen", "belief_in", "belief_todo",
         "belief_freeze", "belief_mat", "belief_new_chain", "belief_percepts"),
        "the rule's scratch tables, empty between runs",
    ),
}  # fmt: skip
#: What a refused write on a standby says.
STANDBY = "is a hot standby (a read-only replica) and refused this"
#: Read commands as users type them (after ``toaster --db URL``).
READS = [
    ["beliefs", "show", "SALLY", "--at", "4s"],
    ["beliefs", "show", "ANNE", "--about", "SALLY", "--at", "4s"],
    ["beliefs", "diff", "SALLY", "--at", "4s"],
    ["beliefs", "history", "--subject", "MARBLE", "--property", "IsIn"],
    ["beliefs", "holders"],
    ["beliefs", "value", "SALLY", "--subject", "MARBLE", "--property", "IsIn", "--target",
     "BASKET", "--at", "4s"],
    ["beliefs", "config"],
    ["get-info", "FACT", "CURRENT", "--agent", "SALLY", "--json"],
    ["get-info", "FACT", "OLD", "--agent", "SALLY"],
    ["get-info", "FACT", "ALL", "--agent", "ROBOT", "--csv"],
    ["get-info", "EVENT", "--json"],
    ["get-info", "AGENT"],
    ["get-info", "ENTITY"],
    ["db", "current"],
    ["db", "check"],
]  # fmt: skip


def docs_sql(marker: str) -> str:
    """The ```sql block of docs/databases.md that holds ``marker`` (the recipe is tested)."""
    blocks = re.findall(r"```sql\n(.*?)```", DOCS.read_text(), re.S)
    found = [b for b in blocks if marker in b]
    assert len(found) == 1, f"docs/databases.md has {len(found)} sql blocks with {marker!r}"
    return found[0]


def invoke(url: str, args: list[str]) -> str:
    """``toaster --db URL ARGS`` through click: its output (exit 0)."""
    result = CliRunner().invoke(cli, ["--db", url, *args])
    assert result.exit_code == 0, (args, result.output, result.exception)
    return result.output


def cli_answers(url: str, out: Path) -> dict[str, str]:
    """Every read command's output, and every export's file."""
    out.mkdir()
    answers = {" ".join(args): invoke(url, args) for args in READS}
    for kind in ("facts", "memory", "history", "events"):
        path = out / f"{kind}.csv"
        invoke(url, ["export", kind, str(path)])
        answers[f"export {kind}"] = path.read_text()
    return answers


def library_answers(url: str) -> dict[str, Any]:
    """The library's answers: beliefs of every holder at every second, false beliefs,
    memory, history, events."""
    db = toaster.connect(url)
    try:
        holders = toaster.beliefs.holders(db)
        self_id = toaster.beliefs.self_agent(db)
        answers: dict[str, Any] = {"holders": holders}
        for t in range(7):
            for holder in (self_id, *holders):
                answers[f"{holder} at {t}"] = queries.beliefs_at(db, holder, t * SECOND)
            answers[f"false at {t}"] = toaster.false_beliefs(db, "SALLY", at=t * SECOND)
            answers[f"false about at {t}"] = toaster.false_beliefs(
                db, "ANNE", about="SALLY", at=t * SECOND
            )
        answers["memory"] = queries.memory(db)
        answers["history"] = queries.history(db)
        answers["events"] = queries.events(db)
        answers["current"] = queries.current_facts(db)
    finally:
        db.close()
    return answers


def unordered(answers: dict[str, Any]) -> dict[str, Any]:
    """``answers`` with each one's rows (lines) sorted. Listings are ordered by time, then by
    the id of the fact or event, which an agent's own row and the rows of the holders that
    follow it share: a standby (the same pages, the same plans) lists such ties in the
    primary's order, an archive may not."""

    def rows(value: Any) -> list[str]:
        return sorted(value.splitlines() if isinstance(value, str) else map(repr, value))

    return {key: rows(value) for key, value in answers.items()}


def write_story(url: str, *, told_at_s: int | None = None) -> None:
    """The Sally-Anne story (and, ``told_at_s``, Anne telling Sally a lie then)."""
    db = toaster.connect(url)
    try:
        if told_at_s is None:
            toaster.beliefs.replay(db, STORY)
        else:
            toaster.tell(
                db, "ANNE", Fact("MARBLE", "IsIn", "BASKET"), listeners=["SALLY"],
                t_ns=told_at_s * SECOND,
            )  # fmt: skip
    finally:
        db.close()


# -- a primary and its hot standby -----------------------------------------------------------


class Pair(NamedTuple):
    primary: Cluster
    standby: Cluster

    @property
    def urls(self) -> tuple[str, str]:
        return self.primary.url("site"), self.standby.url("site")


def replayed(primary: Cluster, standby: Cluster) -> None:
    """Wait until the standby has replayed everything the primary has written so far."""
    lsn = primary.scalar("SELECT pg_current_wal_lsn()::text")
    standby.wait_for("SELECT pg_last_wal_replay_lsn() >= CAST(:lsn AS pg_lsn)", lsn=lsn)


@pytest.fixture(scope="module")
def pair() -> Iterator[Pair]:
    """A primary (wal_level replica) with a story in database ``site``, and a hot standby
    made by pg_basebackup -R that has replayed it."""
    with clusters() as made:
        primary = made.new("primary", wal_level="replica")
        standby = made.standby(primary, "standby")
        assert standby.scalar("SELECT pg_is_in_recovery()") is True
        primary.execute("CREATE DATABASE site", autocommit=True)  # replicated too
        write_story(primary.url("site"))
        write_story(primary.url("site"), told_at_s=6)
        replayed(primary, standby)
        yield Pair(primary, standby)


@pytest.mark.slow
def test_standby_answers_reads_exactly_as_its_primary(pair: Pair, tmp_path: Path) -> None:
    """The CLI's read commands and exports, and the library's queries, on the standby give the
    primary's answers: opening a database at head for reading writes nothing (a standby
    refuses every write)."""
    primary_url, standby_url = pair.urls
    primary = cli_answers(primary_url, tmp_path / "primary")
    standby = cli_answers(standby_url, tmp_path / "standby")
    assert standby == primary
    assert "MARBLE\tIsIn\tBASKET\t\ttrue" in primary["beliefs diff SALLY --at 4s"]
    assert library_answers(standby_url) == library_answers(primary_url)


@pytest.mark.slow
def test_standby_with_the_real_command(pair: Pair) -> None:
    """``python -m toaster`` as users run it: a read gives the primary's lines; a write is
    one line naming the fix (write to the primary), no traceback; so is read-only SQL, which
    a standby cannot guard."""
    primary_url, standby_url = pair.urls

    def run(url: str, *args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "toaster", "--db", url, *args],
            capture_output=True, text=True, timeout=120, cwd=ROOT, check=False,
        )  # fmt: skip

    read = ("beliefs", "diff", "SALLY", "--at", "4s")
    assert run(standby_url, *read).stdout == run(primary_url, *read).stdout != ""
    writes = {
        ("set-info", "ENTITY", "--id", "CUP", "--type", "object"): STANDBY,
        ("tell", "ANNE", "MARBLE", "IsIn", "BOX", "--to", "SALLY"): STANDBY,
        ("beliefs", "replay", str(STORY)): STANDBY,
        ("beliefs", "config", "depth", "3"): STANDBY,
        ("watch", "--timeout", "1"): STANDBY,  # LISTEN, refused during recovery
        ("execute", "SQL", "SELECT count(*) FROM facts"): "read-only SQL cannot run on a hot",
    }
    for args, fix in writes.items():
        proc = run(standby_url, *args)
        assert proc.returncode == 1, (args, proc.stdout, proc.stderr)
        assert "Traceback" not in proc.stderr, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("Error: "), proc.stderr
        assert fix in lines[0] and "run it on the primary" in lines[0], lines[0]
    assert run(primary_url, "execute", "SQL", "SELECT count(*) FROM facts").returncode == 0


@pytest.mark.slow
def test_standby_refuses_library_writes(pair: Pair) -> None:
    """The library opens the standby, reads, and a write raises toaster's one-line error."""
    db = toaster.connect(pair.urls[1])
    try:
        assert toaster.false_beliefs(db, "SALLY", at=4 * SECOND)
        with pytest.raises(toaster.ToasterError, match=re.escape(STANDBY)):
            db.store().assert_fact("ROBOT", Fact("MARBLE", "IsIn", "BOX"), t_ns=9 * SECOND)
    finally:
        db.close()


@pytest.mark.slow
def test_a_read_only_session_reads_and_refuses_writes_in_one_line() -> None:
    """A session that may not write (default_transaction_read_only) opens a database at head,
    reads it (opening writes nothing), and a write is one line naming the fix."""
    with pg_schema(migrated=True) as url:
        write_story(url)
        read_only = url + "%20-cdefault_transaction_read_only%3Don"
        assert invoke(read_only, ["beliefs", "diff", "SALLY", "--at", "4s"]) == invoke(
            url, ["beliefs", "diff", "SALLY", "--at", "4s"]
        )
        result = CliRunner().invoke(cli, ["--db", read_only, "set-info", "ENTITY", "--id", "CUP"])
        lines = result.output.strip().splitlines()
        assert result.exit_code == 1 and len(lines) == 1, result.output
        assert "is read-only" in lines[0] and "default_transaction_read_only off" in lines[0]


# -- logical replication of the memory into an archive -----------------------------------------


class Servers(NamedTuple):
    site: Cluster
    archive: Cluster


@pytest.fixture(scope="module")
def servers() -> Iterator[Servers]:
    """A site server (wal_level logical) and an archive server; each test makes its own
    databases on them."""
    with clusters() as made:
        site = made.new("site", wal_level="logical")
        archive = made.new(
            "archive", max_logical_replication_workers="8", max_worker_processes="16"
        )
        yield Servers(site, archive)


def with_schema(url: str, name: str | None) -> str:
    return url if name is None else f"{url}?options=-csearch_path%3D{name}"


def new_database(cluster: Cluster, name: str, schema_name: str | None = None) -> str:
    """A new database (with ``schema_name``, if given) migrated to head: its toaster URL."""
    cluster.execute(f"CREATE DATABASE {name}", autocommit=True)
    if schema_name is not None:
        cluster.execute(f"CREATE SCHEMA {schema_name}", name)
    url = with_schema(cluster.url(name), schema_name)
    invoke(url, ["db", "upgrade"])  # the recipe's step: same revision as the site
    return url


def publish(site: Cluster, database: str, schema_name: str | None = None) -> None:
    """The docs' CREATE PUBLICATION, run on the site's database (in its schema)."""
    search = "" if schema_name is None else f"SET search_path = {schema_name};\n"
    site.execute(search + docs_sql("CREATE PUBLICATION toaster_memory"), database)


def subscribe(
    servers: Servers, name: str, database: str, into: str, *, user: str = "postgres", **with_: str
) -> None:
    """The docs' CREATE SUBSCRIPTION, connecting to the site's ``database``, run on the
    archive's database ``into``."""
    connection = f"host=127.0.0.1 port={servers.site.port} dbname={database} user={user}"
    sql = docs_sql("CREATE SUBSCRIPTION")
    sql = re.sub(r"CREATE SUBSCRIPTION \w+", f"CREATE SUBSCRIPTION {name}", sql)
    sql = re.sub(r"CONNECTION '[^']*'", f"CONNECTION '{connection}'", sql)
    if with_:
        options = ", ".join(f"{k} = {v}" for k, v in with_.items())
        sql = sql.rstrip().rstrip(";") + f" WITH ({options});"
    servers.archive.execute(sql, into, autocommit=True)


def caught_up(servers: Servers, name: str, into: str) -> None:
    """Wait until subscription ``name`` has copied every table and applied everything the
    site has written so far."""
    count = len(published())
    servers.archive.wait_for(
        "SELECT count(*) FILTER (WHERE r.srsubstate = 'r') = :n FROM pg_subscription_rel r "
        "JOIN pg_subscription s ON s.oid = r.srsubid WHERE s.subname = :name",
        into, n=count, name=name,
    )  # fmt: skip
    lsn = servers.site.scalar("SELECT pg_current_wal_lsn()::text")
    servers.site.wait_for(
        "SELECT coalesce(bool_and(confirmed_flush_lsn >= CAST(:lsn AS pg_lsn)), false) "
        "FROM pg_replication_slots WHERE slot_name = :name",
        lsn=lsn, name=name,
    )  # fmt: skip


def published() -> list[str]:
    """The tables the docs' publication names."""
    sql = docs_sql("CREATE PUBLICATION toaster_memory")
    names = sql.split("FOR TABLE", 1)[1].split(";", 1)[0]
    return [n.strip() for n in names.split(",")]


def table_rows(cluster: Cluster, database: str, schema_name: str, table: str) -> list[str]:
    """Every row of a table as text, sorted (floats print exactly: extra_float_digits 1)."""
    engine_rows = cluster.scalar(
        f"SELECT coalesce(array_agg(t::text ORDER BY t::text), ARRAY[]::text[]) "
        f'FROM {schema_name}."{table}" t',
        database,
    )
    assert isinstance(engine_rows, list)
    return engine_rows


def same_memory(servers: Servers, site: tuple[str, str], archive: tuple[str, str]) -> None:
    """Every published table of the archive holds exactly the site's rows."""
    for table in published():
        site_rows = table_rows(servers.site, *site, table)
        assert table_rows(servers.archive, *archive, table) == site_rows, table


def test_the_publication_names_every_table_of_the_memory() -> None:
    """Every table of toaster's schema is published or excluded for a reason: a table added
    by a migration must be placed (and the docs' recipe updated)."""
    tables = {t.name for t in schema.metadata.sorted_tables} | {"alembic_version"}
    assert set(published()) | set(NOT_PUBLISHED) == tables
    assert not set(published()) & set(NOT_PUBLISHED)
    grant = docs_sql("CREATE ROLE toaster_archive").split("GRANT SELECT ON", 1)[1]
    assert [n.strip() for n in grant.split(" TO ", 1)[0].split(",")] == published()


@pytest.mark.slow
def test_archive_holds_the_sites_memory(servers: Servers, tmp_path: Path) -> None:
    """A site publishes its memory, an archive at the same revision subscribes (the first
    half of the story copied, the rest streamed): the archive's rows equal the site's, no
    trigger fired on the archive (the apply worker runs as replica: no belief run, no holder
    added, the agents' version untouched), and toaster reads the archive as the site."""
    site, archive = servers
    site_url = new_database(site, "one")
    write_story(site_url)  # before the subscription: copied
    publish(site, "one")
    site.execute(docs_sql("CREATE ROLE toaster_archive"), "one")
    archive_url = new_database(archive, "one_archive")
    subscribe(servers, "one_archive", "one", "one_archive", user="toaster_archive")
    write_story(site_url, told_at_s=6)  # after: streamed
    caught_up(servers, "one_archive", "one_archive")
    same_memory(servers, ("one", "public"), ("one_archive", "public"))
    assert archive.scalar("SELECT agents_version FROM store_state", "one_archive") == 0
    assert site.scalar("SELECT agents_version FROM store_state", "one") != 0
    assert archive.scalar("SELECT is_called FROM belief_runs_id_seq", "one_archive") is False
    triggers = "SELECT count(*) FROM pg_trigger WHERE NOT tgisinternal AND tgenabled IN ('A', 'R')"
    assert archive.scalar(triggers, "one_archive") == 0  # none fires for the apply worker
    invoke(archive_url, ["db", "views"])  # DDL is not replicated: the per-agent views
    assert unordered(library_answers(archive_url)) == unordered(library_answers(site_url))
    assert unordered(cli_answers(archive_url, tmp_path / "archive")) == unordered(
        cli_answers(site_url, tmp_path / "site")
    )


@pytest.mark.slow
def test_one_archive_database_cannot_hold_two_sites(servers: Servers) -> None:
    """Two sites' surrogate ids (and people's ids) collide: a second site subscribed into the
    same archive database fails on the first duplicate key (and, disable_on_error, stops)."""
    site, archive = servers
    if int(str(archive.scalar("SHOW server_version_num"))) < 150000:
        pytest.skip("disable_on_error needs PostgreSQL 15")
    for name in ("two_a", "two_b"):
        write_story(new_database(site, name))
        publish(site, name)
    new_database(archive, "two_archive")
    subscribe(servers, "two_a", "two_a", "two_archive")
    caught_up(servers, "two_a", "two_archive")
    subscribe(servers, "two_b", "two_b", "two_archive", disable_on_error="true")
    archive.wait_for("SELECT NOT subenabled FROM pg_subscription WHERE subname = 'two_b'",
                     "two_archive")  # fmt: skip
    errors = "SELECT sync_error_count + apply_error_count FROM pg_stat_subscription_stats "
    assert archive.scalar(errors + "WHERE subname = 'two_b'", "two_archive") != 0
    assert "duplicate key value violates unique constraint" in archive.log()
    same_memory(servers, ("two_a", "public"), ("two_archive", "public"))


@pytest.mark.slow
def test_archive_of_several_sites_a_schema_each(servers: Servers) -> None:
    """Sites whose toaster lives in a schema of its own name (site_a, site_b) archive into
    one database, a schema each: both are whole, and toaster reads each as its site."""
    site, archive = servers
    urls = {}
    for name in ("site_a", "site_b"):
        urls[name] = new_database(site, name, name)
        write_story(urls[name])
        publish(site, name, name)
    archive.execute("CREATE DATABASE several", autocommit=True)
    for name in ("site_a", "site_b"):
        archive.execute(f"CREATE SCHEMA {name}", "several")
        invoke(with_schema(archive.url("several"), name), ["db", "upgrade"])
        subscribe(servers, name, name, "several")
    write_story(urls["site_b"], told_at_s=6)
    for name in ("site_a", "site_b"):
        caught_up(servers, name, "several")
        same_memory(servers, (name, name), ("several", name))
        archived = with_schema(archive.url("several"), name)
        invoke(archived, ["db", "views"])
        assert unordered(library_answers(archived)) == unordered(library_answers(urls[name]))
    collide = "SELECT count(*) FROM site_a.facts a JOIN site_b.facts b USING (id)"
    assert archive.scalar(collide, "several") != 0  # one schema could not hold both
