"""Migrations: the schema they build equals schema.py; up, down, up again on both backends."""

from __future__ import annotations

import hashlib
import itertools
import json
import re
import sqlite3
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect, text

import toaster
import toaster.queries as q
from tests.conftest import pg_schema
from tests.migrations import beliefs_story
from toaster.db import migrate
from toaster.db.engine import make_engine
from toaster.db.schema import metadata
from toaster.errors import SchemaOutdatedError
from toaster.migrations import frozen_triggers


@pytest.mark.slow
def test_migrations_match_the_declared_schema(empty_url: str) -> None:
    """Upgrading an empty database yields exactly the tables and indexes of schema.py."""
    engine = make_engine(empty_url)
    migrate.upgrade(engine)
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), metadata)
    engine.dispose()
    assert diff == []


@pytest.mark.slow
def test_upgrade_downgrade_upgrade(empty_url: str) -> None:
    """Down to base removes every table and view (agents' views included); up again works."""
    with toaster.connect(empty_url) as db:
        db.store().add_entity("SALLY", "human")
    engine = make_engine(empty_url)
    migrate.downgrade(engine, "base")
    with engine.connect() as conn:
        inspector = inspect(conn)
        assert inspector.get_view_names() == []
        assert set(inspector.get_table_names()) <= {"alembic_version"}
    migrate.upgrade(engine)
    assert migrate.current_revision(engine) == migrate.head_revision()
    engine.dispose()


def test_new_database_is_created_and_old_one_refused(empty_url: str) -> None:
    """A new database is migrated on first use; one behind the code gets the fix in the error."""
    engine = make_engine(empty_url)
    migrate.upgrade(engine, "0001")
    engine.dispose()
    if migrate.head_revision() == "0001":
        pytest.skip("only one revision exists")
    with pytest.raises(SchemaOutdatedError, match="run `toaster db upgrade"):
        toaster.connect(empty_url)


@pytest.mark.slow
def test_empty_database_is_created_on_first_use(empty_url: str) -> None:
    """connect() on an empty database migrates it to head."""
    with toaster.connect(empty_url) as db:
        assert migrate.current_revision(db.engine) == migrate.head_revision()


@pytest.mark.slow
def test_downgrade_with_nested_holders_named_oddly(empty_url: str) -> None:
    """Agents and nested holders whose ids hold ':', '%', quotes are dropped cleanly."""
    from toaster import Fact
    from toaster.beliefs import api

    odd = ["a:b %s", 'c\'d "e"']
    with toaster.connect(empty_url) as db:
        store = db.store()
        store.add_entity("R", "robot", is_self=True, t_ns=0)
        for agent in odd:
            store.add_entity(agent, "human", t_ns=0)
        store.add_entity("MUG", "object", t_ns=0)
        room = [Fact(agent, "IsInRoom", "LAB") for agent in odd] + [Fact("MUG", "IsInRoom", "LAB")]
        store.sync_snapshot("s", "R", 1, room)
        store.sync_snapshot("s", "R", 2, [*room, Fact("MUG", "IsOn", "TABLE")])
        assert f"{odd[0]}>{odd[1]}" in api.holders(db)
    engine = make_engine(empty_url)
    migrate.downgrade(engine, "base")
    with engine.connect() as conn:
        assert inspect(conn).get_view_names() == []
    engine.dispose()


# -- Databases from before the belief revisions were squashed (0002 + 0003 -> 0003) ---------

LEGACY_DUMP = Path(__file__).parent / "data" / "beliefs_0005.sql"
TICKS = [t * 10 for t in range(9)]


def _timelines(db: toaster.Database) -> dict[str, Any]:
    """Every holder's history, events and as-of beliefs at each tick (write times left out)."""
    from toaster.beliefs import api

    return {
        holder: (
            sorted(row._replace(recorded_ns=0) for row in q.history(db, holder)),
            sorted(row[1:17] for row in q.events(db, holder)),  # no id, no recorded_ns
            [
                sorted(row._replace(recorded_ns=0) for row in q.beliefs_at(db, holder, t))
                for t in TICKS
            ],
        )
        for holder in ["R", *api.holders(db)]
    }


def _schema_matches(engine: Any) -> None:
    with engine.connect() as conn:
        assert compare_metadata(MigrationContext.configure(conn), metadata) == []
        assert "belief_rules" not in inspect(conn).get_table_names()


@pytest.mark.slow
def test_a_database_written_before_the_squash_upgrades(tmp_path: Path) -> None:
    """A SQLite database written at 0005 by the code of the unsquashed 0002/0003 (data dump):
    it upgrades to the declared schema, reads the same, and the rules go on: the robot's
    timeline and the holders are those of a database made now, every holder's timeline stays
    well formed. (The holders' first half differs from a database made now: 0009 changed what
    a move shows, so their continuations are not compared row for row.)"""
    old = tmp_path / "old.db"
    raw = sqlite3.connect(old)
    raw.executescript(LEGACY_DUMP.read_text(encoding="utf-8"))
    raw.close()
    engine = make_engine(f"sqlite:///{old}")
    assert migrate.current_revision(engine) == "0005"
    with engine.connect() as conn:
        before = conn.exec_driver_sql("SELECT * FROM fact_history ORDER BY fact_id, key_id").all()
    migrate.upgrade(engine)
    _schema_matches(engine)
    with engine.connect() as conn:
        assert (
            conn.exec_driver_sql("SELECT * FROM fact_history ORDER BY fact_id, key_id").all()
            == before
        )
        views: dict[str, str] = dict(
            conn.exec_driver_sql("SELECT name, sql FROM sqlite_master WHERE type = 'view'").all()
        )
        # Nested holders moved out of entities and agents into holders (revision 0008).
        nested = conn.exec_driver_sql("SELECT id, depth FROM holders WHERE depth >= 2").all()
        assert nested and all(">" in h for h, _ in nested)
        assert (
            conn.exec_driver_sql(
                "SELECT count(*) FROM entities WHERE kind = 'belief' OR id LIKE '%>%'"
            ).scalar()
            == 0
        )
        assert conn.exec_driver_sql("SELECT count(*) FROM agents WHERE id LIKE '%>%'").scalar() == 0
    engine.dispose()
    fresh = tmp_path / "fresh.db"
    with toaster.connect(f"sqlite:///{fresh}") as db:
        beliefs_story.first_half(db)
        with db.transaction() as conn:
            assert (
                dict(
                    conn.exec_driver_sql(
                        "SELECT name, sql FROM sqlite_master WHERE type = 'view'"
                    ).all()
                )
                == views
            )
        expected = _timelines(db)
        beliefs_story.second_half(db)
        expected_after = _timelines(db)
    with toaster.connect(f"sqlite:///{old}") as db:
        got = _timelines(db)
        assert got["R"] == expected["R"] and got.keys() == expected.keys()
        beliefs_story.second_half(db)
        got = _timelines(db)
        assert got["R"] == expected_after["R"] and got.keys() == expected_after.keys()
        for holder in got:
            _assert_well_formed(q.history(db, holder))


def _assert_well_formed(rows: list[Any]) -> None:
    """Per key: intervals in order, none overlapping, at most the last one open."""
    by_key: dict[tuple[Any, ...], list[Any]] = {}
    for row in rows:
        key = (
            row.subject_id,
            row.subject_owner_id,
            row.property,
            row.sub_property,
            row.target_id,
            row.target_owner_id,
        )
        by_key.setdefault(key, []).append(row)
    for key, intervals in by_key.items():
        intervals.sort(key=lambda r: r.valid_from_ns)
        for a, b in itertools.pairwise(intervals):
            assert a.valid_to_ns is not None and a.valid_to_ns <= b.valid_from_ns, key


@pytest.mark.slow
def test_a_database_at_the_previous_head_upgrades(empty_url: str, tmp_path: Path) -> None:
    """Both backends: a database as 0005 left it (defaults stored as settings rows, the
    ``belief_rules`` table of the unsquashed 0002) upgrades and the rules go on unchanged."""
    with toaster.connect(empty_url) as db:
        beliefs_story.first_half(db)
        expected = _timelines(db)
    engine = make_engine(empty_url)
    migrate.downgrade(engine, "0005")
    with engine.begin() as conn:
        conn.exec_driver_sql(
            "CREATE TABLE belief_rules (backend TEXT NOT NULL, step TEXT NOT "
            "NULL, sql_text TEXT NOT NULL, CONSTRAINT pk_belief_rules "
            "PRIMARY KEY (backend, step))"
        )
        conn.exec_driver_sql(
            "INSERT INTO belief_rules VALUES ('sqlite', '99_clear', 'DELETE FROM belief_changed')"
        )
    migrate.upgrade(engine)
    _schema_matches(engine)
    engine.dispose()
    with toaster.connect(f"sqlite:///{tmp_path / 'fresh.db'}") as fresh:
        beliefs_story.first_half(fresh)
        beliefs_story.second_half(fresh)
        expected_after = _timelines(fresh)
    with toaster.connect(empty_url) as db:
        assert _timelines(db) == expected
        beliefs_story.second_half(db)
        assert _timelines(db) == expected_after  # the same as SQLite's, written now


#: The sha256 of every released frozen trigger file. A database migrated through a revision
#: holds exactly its file's triggers, so a released file never changes: a rule change is a new
#: revision with a file of its own, pinned here when it is released.
RELEASED_FROZEN = {
    "0007_triggers.json": "e63fc43ff4c21f67058f8094f57a937e444b715e3dabccffe3b4c67e28cff5b0",
    "0008_triggers.json": "3aa9ba3afc530fd351615c3d1424f28b43edb3dadef5c6d79eb601a3388932dd",
    "0009_triggers.json": "2ea049aa6b38310dcadc010e6ddfdec9fb4427a8a54f17b35f9f777a8d4fc503",
    "0010_triggers.json": "4d521db3badf27fbf94e2431a8ee17524c4fbb02929e3eac9e2539ad47aa2e61",
    "0011_triggers.json": "1e3b6c26f967f398e3f99bd450c0ff1bbb789477dcd0b4020671cea002aadf64",
    "0012_triggers.json": "22e6d469450a7363c40017a8f784cde45bda3050518c5213b7c9900952640885",
    "0013_triggers.json": "547f86302e3d674714215160c0860f974d44e24dbe1bd2ded68a79856a4007b5",
    "0014_triggers.json": "a7a9a5db02fb811c6b6286df5d1a33268b2de2a0e495f5e2033620ed543a825c",
    "0015_triggers.json": "4c713be8ba342c5d22b2af7c9948e6d9e5287ddf053170e60cf8d17bad2cf436",
    "0016_units.json": "15c95a258d87e77bdefa006aa8888c6c875b961ff5e7d3d43e7edb9757ef9eaf",
    "0016/00_temp.json": "c12335edcfede1317721389cc215aba4e9e86fb20460d49d0ddffc76eab4fa37",
    "0016/10_focus.json": "254378fcc680a1752759c80498a4992e1d433c0e7c8d5ee04da3d5ac7ab9a40a",
    "0016/12_moves.json": "ac1e88ee9b6020bc168d4bafc460ca474b221a312b4c0faf224d6e4ed3ff3481",
    "0016/13_late.json": "989f88d91ba75af8c7d32a628413ccb39c4759c0b480836027b597d3dbc4ca9d",
    "0016/15_ungroup.json": "19f03a072cd524aaecf983782f5b1aa9adcee3b1dfee34be66f1d829190d374e",
    "0016/20_perceive_0_around.json": "f90a8a7a1a448247b10f753caadbb2dc1351c9abf57f0b6ab8792adec730e3d6",
    "0016/20_perceive_1_after.json": "3dac6e5c4266bf2339851a3338f23e51ff20675b454d4cff6cca330b6757e2f6",
    "0016/20_perceive_1_before.json": "1d4d76fbb7e80c3433dbf889a2ce995b082de509893f9d09371c85425a16191f",
    "0016/30_changes_0.json": "c93645297c2c58ebd486d12bfb3fcfa3271909efcd5c8c763e07d32682cc7014",
    "0016/30_changes_1.json": "7fb0ff5472685c086f71cd27007108b6ceb0c59f2eda2d0d7baea6f1c739d69c",
    "0016/32_expand.json": "f93aa4c22aba6102ebfe04e956795739f61b3c0324cd4b46af04f85c8b34b0ed",
    "0016/35_freeze.json": "a06653c345157c8f1e6e003654d0517e5546d315bf938548bf47ace3de19baab",
    "0016/40_refresh.json": "cdded6aa39a2c7a2dc8a9fba6c46039c21e4aeab5b3c7f31153a93efea06f653",
    "0016/42_keep_max.json": "4c7b2bbeb60f165c946c372b3e31f31cbb950c991afdc3d58f1960aaf1f14631",
    "0016/45_resolve.json": "4901028b0bb87e920d0a5f32335df32ebc12d19daddbafed67ca8928d7e8fafd",
    "0016/50_keys.json": "678e2e336ab32997c7b1891518bb5d33ff12897a2b5d70aa8f88acbad179c3ec",
    "0016/55_switch.json": "6e60bbb61a42cf3043de9a7f559ab16aa93f8ac720bf66498e3d0ea2a0644bdb",
    "0016/58_frozen.json": "71a29bc52700a1c42347e40ede6f07c6e1f93108ce8b5305db46aa91643b72f7",
    "0016/60_plan.json": "7baa34fdc819ec26f5c3f39b87861e8bee67401f05dc2bc6c4959b44f545209a",
    "0016/70_events.json": "376ee5fe9161d59606d68839659c06489ca241e2f83510b8661f34e3fc9eebf9",
    "0016/80_close.json": "01e495902e6fedfc793de2fc23eec653c5893494cc2efe54022cb119215e6c2d",
    "0016/85_refresh_rows.json": "3ef801b0ad66d9100ade6b97d27cd4bbd6b752c6caa4a4915eb06e32b4238015",
    "0016/90_follow.json": "ed89a30b642f843b6ae5c6bd6e13f0c4527408ebd4f5622691d5b71701479f7e",
    "0016/91_open.json": "791f46867f49e64410049f01299d0d2c8b13bfabf03486b185968b78294841b9",
    "0016/92_repconf.json": "877a4ab34803186085a4c9dbf1c013a8caf54aec8853f55c0af0c4d8fef782a0",
    "0016/94_keep_groups.json": "5ba876db4d0e452ec3bc70c0e782fc266d46a130bc68084a7ce5d6c3812f574e",
    "0016/96_regroup.json": "b6c0b5ca5a7a4954b9316b4141b28c3f9a96e0a7882e1b86631c482cf7b49c69",
    "0016/99_clear.json": "5068a7e7332dbc0e5c344cf318c05cc9a9987e2c50f1bf69b072ad91a75f39ba",
    "0016/holders.json": "7adb6c895373dbdbc34800939eca530ddc0bf3b6c86cf358587ecd8fccd27ee6",
    "0016/holders_seen.json": "0a2385798a3cc7b406b737e8c2e648d6e800b4b16330626e3e815f7e43ce2cc0",
    "0016/inbox.json": "52c8e35406bc33088a740f10aa05824d5354a107eccf66f4164e44eb72b9fc6a",
    "0016/pipeline.json": "2cd0b616cefbf61ebcfc65a39112438ad253242fde55c8fb8a809498a12dd252",
    "0016/reperceive.json": "135c9e86cf9d73fb4d44164a57a78491b43c0dd872d94d3de0dfc431fdf1c4dd",
    "0016/ungroup.json": "3f38619715bb5f9b468e20ff9bcc93255a26f476ede03caac98d64b047e22a0a",
    "0017_agent_views.json": "995cb30a52dc1255763c94f1f41a58851767b1c7b9807dcf52585f192320d41b",
    "0018_units.json": "ec0755fb7c50ca50b2d2a8cc7c2507940051cbbe4ca4561c35fa2730bc80dfdd",
    "0018/40_refresh.json": "e95276160960c276727e18fad48dda8394da62081f10f9e8e18323f71d4b3448",
    "0019_units.json": "a6ed8555dac949ccd8c95f5c0b1c4efa47e5b66877c9ffd8f1b8bdb8770dac2f",
    "0019/10_focus.json": "c6ea450f2bc9fac01c14c30836edf0131362c5b3caae1f35baa3fb7dc4b3f752",
    "0023_units.json": "405ded312a2c2dc26cec916a8a97996460d5d3e1a3da9dae3292362fd41f6f2f",
    "0023/15_ungroup.json": "bdde86e16bf5784c24a37e52be4fc1a0ea4b4132e188b57b1085a3b1f7c1c28f",
    "0023/19_settled.json": "019fd1fa5a284a233201dd957f6d1ab2142ddd391c215dd68f1bd215c6c98d74",
    "0023/20_reuse.json": "3a8f4cebee8877eb1a7562781ac238ee4a84421cf72676e2cc207e1a64f0acfa",
    "0023/21_remember.json": "f277226a7bac281d9405a8434b119e06e9b956ced763c2f36e413a6e0be3d749",
    "0023/58_frozen.json": "9e3658220d855d4b6e3bee204fd0affa4188997c9d92a00d3228770c5e8a6a9d",
    "0023/85_refresh_rows.json": "311db5279a10fb515f1c20f1e06a43f1fdb5cdcb34e0d8d8b2d81dc1348b037c",
    "0023/94_keep_groups.json": "0a09293b811691d15c21232aeed16fde5102ff914bb4156837733ad3cd3f6bdc",
    "0023/97_unsettle.json": "49d37a14ff0cc42b93482b0509a11e4ecec7c77e515477d5ba754f39c14a6ab7",
    "0023/98_settle.json": "7cda26c5d0304ed152a408e172d3d33ec91b6920f0b8f81cb281988d6f557b50",
    "0023/inbox.json": "c0332ed4591d72ec5401a9edc8d322fee68d575c458d5cfd0bbab732675c8b11",
    "0023/pipeline.json": "c30a08a1070a5145f246bdd7ae29f323626fdc7dd78533464aaf35cd7cfaa264",
    "0023/reperceive.json": "999c874f2be66ea245db233daf8a9431715cb59197aa0f0054451af790143578",
    "0023/ungroup.json": "096487ff1bac36092294329db7db8f488b9be07f726273eb412d806c398c6296",
    "0027_units.json": "d2a4da56e17eccf435c13f01721f50ba5b68c9b25be9672c517c2dd1374de84a",
    "0027/20_perceive.json": "dfea02b1b67a05f599c4181b865a9ff9aae8ee47818f5fafa4d2f6d2fb5b83d5",
    "0027/20_perceive_0_around.json": (
        "3f6a3d26b4d3141772fc9560f95f966e31320a9b6b670ebbbea90c52261ee756"
    ),
    "0027/20_perceive_1_after.json": (
        "780ff16c76f00ec68b1d88c7e40c3e3668610336df6fd67c1399bbf5d7a22676"
    ),
    "0027/20_perceive_1_before.json": (
        "2be1797a0b5d0d4cfb570c0689fc97f5d48ff57733b85cf6e5e4b00596399851"
    ),
    "0028_units.json": "89e974e8d72034202c34c29a143bfa188d9101aa7959c1d4b56306529f394be3",
    "0028/holders.json": "94f3a32447e2bc6ef924be35084d0ddf9809017b2c1c0b56df3c4a020280f988",
    "0028/pipeline.json": "cae06bb17b23d46e239b4855951d997357d0030a36cbbcda25f15a15407dfdb7",
    "0029_units.json": "a42f984607012b1aa8facb911375a878a5569fe01d0bc8473dffaecd75ab1c01",
    "0029/20_perceive.json": "f377b44f44f9100d3e970bd78284d802fd03e48dc5f8ca48bd06e46a0c44ef23",
    "0029/96_regroup.json": "dc3252688837890b592d71652a6b4aa25236bd986263990ea2457607681794fd",
    "0030_units.json": "4a1d0593e6673c06be4f1d358ca9ce085976337ec04ec5435adaeb8e441a5a35",
    "0030/inbox.json": "260ffefd8d7e3ef1a849df2588cf323ddae1bd15afffd75833703a350687ff86",
    "0031_units.json": "9ce49b444942606d0b07a844633cc02e5cdd026be7fe64be47363228756b6b47",
    "0031/pipeline.json": "e8d529dd206d79ccdfd2f0a80743e84431418cefbbd53b8df7f9226399f7fd4f",
}


def test_released_frozen_triggers_never_change() -> None:
    frozen = Path(toaster.__file__).parent / "migrations" / "frozen"
    found = {
        path.relative_to(frozen).as_posix(): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in frozen.rglob("*.json")
    }
    changed = sorted(name for name in RELEASED_FROZEN if found.get(name) != RELEASED_FROZEN[name])
    assert not changed, f"released frozen triggers changed: {changed} (write a new revision)"
    assert sorted(found) == sorted(RELEASED_FROZEN), "pin a new revision's frozen file here"


def test_the_package_ships_every_frozen_file() -> None:
    """The wheel's package data (pyproject.toml) takes the unit files in their folders too."""
    package = Path(toaster.__file__).parent
    pyproject = package.parents[1] / "pyproject.toml"
    if not pyproject.exists():
        pytest.skip("an installed package: no pyproject.toml beside it")
    globs = tomllib.loads(pyproject.read_text(encoding="utf-8"))["tool"]["setuptools"][
        "package-data"
    ]["toaster"]
    for path in (package / "migrations" / "frozen").rglob("*.json"):
        relative = path.relative_to(package)
        assert any(
            relative.match(glob) and len(relative.parts) == len(Path(glob).parts) for glob in globs
        ), relative


# -- Revision 0016: the rule's triggers per unit ------------------------------------------------


def _normal(sql: str) -> str:
    return re.sub(r"\s+", " ", sql).strip()


def _rule_objects(engine: Any) -> set[str]:
    """The SQL of the rule's triggers (SQLite) or the bodies of its functions (PostgreSQL)."""
    with engine.connect() as conn:
        if engine.dialect.name == "sqlite":
            return {
                _normal(sql)
                for (sql,) in conn.exec_driver_sql(
                    "SELECT sql FROM sqlite_master WHERE type = 'trigger' "
                    "AND name NOT LIKE '%_guard_%' AND name <> 'agents_holder'"
                )
            }
        return {
            _normal(src)
            for (src,) in conn.exec_driver_sql(
                "SELECT prosrc FROM pg_proc WHERE (left(proname, 13) = 'toaster_step_' OR proname IN "
                "('toaster_belief_run', 'toaster_fact_inbox', 'toaster_settings_changed', "
                "'toaster_agents_changed')) AND pronamespace = "
                "(SELECT oid FROM pg_namespace WHERE nspname = current_schema())"
            )
        }


def _frozen_objects(backend: str, create: list[str]) -> set[str]:
    if backend == "postgresql":
        return {_normal(s.split("$fn$")[1]) for s in create if "$fn$" in s}
    return {_normal(s) for s in create}


def _frozen_sets(backend: str) -> dict[str, set[str]]:
    """What revisions 0015, 0016, 0018, 0019, 0023, 0027, 0028 and 0029 install (their frozen files, not
    the package's rendering)."""
    frozen = Path(toaster.__file__).parent / "migrations" / "frozen"
    whole = json.loads((frozen / "0015_triggers.json").read_text(encoding="utf-8"))
    return {
        "0015": _frozen_objects(backend, whole[backend]["create"]),
        **{
            revision: _frozen_objects(
                backend, frozen_triggers.unit_statements(revision, backend, "create")
            )
            for revision in ("0016", "0018", "0019", "0023", "0027", "0028", "0029")
        },
    }


#: Changes written as a plain SQL client would (fact_inbox): the installed rule runs them.
_INBOX = [
    ("assert", "MUG", "Color", "", "purple", 50),
    ("assert", "BOB", "IsInRoom", "HALL", "true", 60),
    ("retract", "MUG", "IsIn", "BOX", "true", 70),
    ("assert", "BOX", "IsClosed", "", "true", 80),
    ("assert", "MUG", "Color", "", "white", 90),
    ("assert", "BOB", "IsInRoom", "LAB", "true", 100),
]


def _inbox_story(url: str, revision: str) -> list[Any]:
    """The story's first half, then :data:`_INBOX` written with the rule of ``revision``:
    every row of every holder (ids and write times left out)."""
    with toaster.connect(url) as db:
        beliefs_story.first_half(db)
    engine = make_engine(url)
    migrate.downgrade(engine, revision)
    with engine.begin() as conn:
        for action, subject, prop, target, value, t in _INBOX:
            conn.execute(
                text(
                    "INSERT INTO fact_inbox (action, agent_id, subject_id, property, target_id, "
                    "value_text, t_ns) VALUES (:a, 'R', :s, :p, :tg, :v, :t)"
                ),
                {"a": action, "s": subject, "p": prop, "tg": target or None, "v": value, "t": t},
            )
    with engine.connect() as conn:
        rows = [
            sorted(tuple(row) for row in conn.exec_driver_sql(sql))
            for sql in (
                "SELECT agent_id, subject_id, property, target_id, value_text, value_num, "
                "confidence, valid_from_ns, valid_to_ns, source FROM fact_history",
                "SELECT agent_id, kind, stamp_ns, subject_id, property, target_id, value_text, "
                "confidence, previous_text, source FROM event_log",
                "SELECT holder_id, position, member_id FROM belief_chain",
            )
        ]
    engine.dispose()
    return rows


@contextmanager
def _another(empty_url: str, tmp_path: Path) -> Iterator[str]:
    """A second empty database on the backend of ``empty_url``."""
    if empty_url.startswith("sqlite"):
        yield f"sqlite:///{tmp_path / 'other.db'}"
        return
    with pg_schema() as url:
        yield url


def test_the_step_units_replace_the_whole_set_and_back(empty_url: str, tmp_path: Path) -> None:
    """0015 <-> 0016 installs exactly each revision's frozen objects, and a plain SQL client's
    writes give the same rows with 0015's whole set as with 0016's units."""
    engine = make_engine(empty_url)
    expected = _frozen_sets(engine.dialect.name)
    assert expected["0015"] != expected["0016"]
    migrate.upgrade(engine, "0015")
    assert _rule_objects(engine) == expected["0015"]
    migrate.upgrade(engine, "0016")
    assert _rule_objects(engine) == expected["0016"]
    migrate.downgrade(engine, "0015")
    assert _rule_objects(engine) == expected["0015"]
    migrate.downgrade(engine, "base")
    engine.dispose()
    with _another(empty_url, tmp_path) as other:
        whole, units = _inbox_story(empty_url, "0015"), _inbox_story(other, "0016")
    assert whole == units
    assert len(whole[0]) > 30 and len({row[0] for row in whole[0]}) > 3  # holders' rows too


def test_a_revision_swaps_the_units_it_changed_and_back(empty_url: str) -> None:
    """0018 <-> 0019 (swap_units: 10_focus, and SQLite's driver that inlines it) installs
    exactly each revision's frozen objects."""
    engine = make_engine(empty_url)
    expected = _frozen_sets(engine.dialect.name)
    if engine.dialect.name == "postgresql":
        assert expected["0018"] != expected["0019"]
    migrate.upgrade(engine, "0018")
    assert _rule_objects(engine) == expected["0018"]
    migrate.upgrade(engine, "0019")
    assert _rule_objects(engine) == expected["0019"]
    migrate.downgrade(engine, "0018")
    assert _rule_objects(engine) == expected["0018"]
    engine.dispose()


def _kept_tables(engine: Any) -> tuple[set[str], set[str]]:
    """The kept perception's tables and store_state's columns that are there."""
    with engine.connect() as conn:
        inspector = inspect(conn)
        tables = set(inspector.get_table_names()) & {"belief_perceived", "belief_settled"}
        columns = {c["name"] for c in inspector.get_columns("store_state")}
    return tables, columns & {"perceived_for", "perceived_ns"}


def test_kept_perception_installs_and_goes_back(empty_url: str, tmp_path: Path) -> None:
    """0022 <-> 0023: the kept perception's tables, columns and rule units come and go (every
    unit replaced: exactly each revision's frozen objects), its tables refuse direct writes,
    and a plain SQL client's writes give the same rows with either revision's rule."""
    engine = make_engine(empty_url)
    expected = _frozen_sets(engine.dialect.name)
    migrate.upgrade(engine, "0022")
    assert _rule_objects(engine) == expected["0019"]
    assert _kept_tables(engine) == (set(), set())
    migrate.upgrade(engine, "0023")
    assert _rule_objects(engine) == expected["0023"] != expected["0019"]
    assert _kept_tables(engine) == (
        {"belief_perceived", "belief_settled"},
        {"perceived_for", "perceived_ns"},
    )
    for table, row in (("belief_perceived", "('A', 'B', 1.0)"), ("belief_settled", "(1, 1)")):
        with pytest.raises(Exception, match=f"{table} is kept by toaster"), engine.begin() as conn:
            conn.exec_driver_sql(f"INSERT INTO {table} VALUES {row}")
    migrate.downgrade(engine, "0022")
    assert _rule_objects(engine) == expected["0019"]
    assert _kept_tables(engine) == (set(), set())
    migrate.downgrade(engine, "base")
    engine.dispose()
    with _another(empty_url, tmp_path) as other:
        old, kept = _inbox_story(empty_url, "0022"), _inbox_story(other, "0023")
    assert old == kept
    assert len(kept[0]) > 30 and len({row[0] for row in kept[0]}) > 3


def test_sqlite_runs_the_perception_step_as_one_trigger_with_the_same_rows(
    empty_url: str, tmp_path: Path
) -> None:
    """0025 <-> 0027 installs exactly each revision's frozen objects; at 0027 SQLite holds the
    perception statement once (a trigger of its own that its five places enter: a connection
    compiles it once, not at each place), and a plain SQL client's writes give the same rows."""
    engine = make_engine(empty_url)
    expected = _frozen_sets(engine.dialect.name)
    migrate.upgrade(engine, "0025")
    assert _rule_objects(engine) == expected["0023"]
    migrate.upgrade(engine, "0027")
    assert _rule_objects(engine) == expected["0027"]
    if engine.dialect.name == "sqlite":
        with engine.connect() as conn:
            holding = conn.exec_driver_sql(
                "SELECT name FROM sqlite_master WHERE type = 'trigger' "
                "AND sql LIKE '%INSERT INTO belief_seen%WITH RECURSIVE%'"
            ).all()
        assert [name for (name,) in holding] == ["belief_step_20_perceive"]
    migrate.downgrade(engine, "0025")
    assert _rule_objects(engine) == expected["0023"]
    migrate.downgrade(engine, "base")
    engine.dispose()
    with _another(empty_url, tmp_path) as other:
        before, after = _inbox_story(empty_url, "0025"), _inbox_story(other, "0027")
    assert before == after
    assert len(after[0]) > 30 and len({row[0] for row in after[0]}) > 3  # holders' rows too


def test_holder_clocks_take_over_the_one_clock_and_give_it_back(
    empty_url: str, tmp_path: Path
) -> None:
    """0027 <-> 0028 installs exactly each revision's frozen objects and moves the rules' clock
    between ``store_state`` and the holders (the latest holder's clock when going back); a
    plain SQL client's writes give the same rows with either rule."""
    engine = make_engine(empty_url)
    expected = _frozen_sets(engine.dialect.name)
    migrate.upgrade(engine, "0027")
    assert _rule_objects(engine) == expected["0027"]
    migrate.upgrade(engine, "0028")
    assert _rule_objects(engine) == expected["0028"]
    migrate.downgrade(engine, "0027")
    assert _rule_objects(engine) == expected["0027"]
    migrate.downgrade(engine, "base")
    with toaster.connect(empty_url) as db:
        beliefs_story.first_half(db)
    clocks = "SELECT DISTINCT clock_ns, clock_self FROM holders WHERE clock_ns IS NOT NULL"
    with engine.connect() as conn:
        latest = max(conn.exec_driver_sql(clocks).all())
    migrate.downgrade(engine, "0027")
    with engine.connect() as conn:
        one = conn.exec_driver_sql("SELECT beliefs_ns, beliefs_self FROM store_state").one()
        assert "clock_ns" not in _columns(conn, "holders")
    assert tuple(one) == tuple(latest)
    migrate.upgrade(engine, "0028")
    with engine.connect() as conn:
        assert conn.exec_driver_sql(clocks).all() == [tuple(latest)]  # every holder at it
        assert "beliefs_ns" not in _columns(conn, "store_state")
    migrate.downgrade(engine, "base")
    engine.dispose()
    with _another(empty_url, tmp_path) as other:
        before, after = _inbox_story(empty_url, "0027"), _inbox_story(other, "0028")
    assert before == after
    assert len(after[0]) > 30 and len({row[0] for row in after[0]}) > 3  # holders' rows too


def _columns(conn: Any, table: str) -> set[str]:
    return {column["name"] for column in inspect(conn).get_columns(table)}


def test_sqlite_perceives_through_a_scratch_table_with_the_same_rows(
    empty_url: str, tmp_path: Path
) -> None:
    """0027 <-> 0029 installs exactly each revision's frozen objects; at 0029 SQLite's
    perception and regrouping statements read the self's perception facts from
    ``belief_percepts`` (filled first, a statement of its own; empty after), PostgreSQL's
    functions are 0028's, and a plain SQL client's writes give the same rows."""
    engine = make_engine(empty_url)
    expected = _frozen_sets(engine.dialect.name)
    migrate.upgrade(engine, "0027")
    assert _rule_objects(engine) == expected["0027"]
    migrate.upgrade(engine, "0029")
    assert _rule_objects(engine) == expected["0029"]
    if engine.dialect.name == "sqlite":
        with engine.connect() as conn:
            reading = conn.exec_driver_sql(
                "SELECT name FROM sqlite_master WHERE type = 'trigger' "
                "AND sql LIKE '%INSERT INTO belief_percepts%FROM belief_percepts%'"
            ).all()
        assert sorted(name for (name,) in reading) == [
            "belief_block_regroup",
            "belief_step_20_perceive",
        ]
    else:
        assert expected["0029"] == expected["0028"]
    migrate.downgrade(engine, "0027")
    assert _rule_objects(engine) == expected["0027"]
    assert "belief_percepts" not in inspect(engine).get_table_names()
    migrate.downgrade(engine, "base")
    engine.dispose()
    with _another(empty_url, tmp_path) as other:
        before, after = _inbox_story(empty_url, "0027"), _inbox_story(other, "0029")
        engine = make_engine(other)
        with engine.connect() as conn:  # a scratch table: empty between runs
            assert conn.exec_driver_sql("SELECT COUNT(*) FROM belief_percepts").scalar() == 0
        engine.dispose()
    assert before == after
    assert len(after[0]) > 30 and len({row[0] for row in after[0]}) > 3  # holders' rows too
