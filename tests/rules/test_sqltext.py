"""The belief rule's SQL: one template per step, rendered per backend by dialect macros."""

from __future__ import annotations

import importlib
import json
import re
from importlib import resources

import pytest
from sqlalchemy import text

import toaster
from toaster.migrations import frozen_triggers
from toaster.rules import hook as rules
from toaster.rules import pipeline, sqltext, triggers

BACKENDS = ("sqlite", "postgresql")
#: What the other backend writes and this one must not see.
FOREIGN = {
    "sqlite": (
        "LEAST(",
        "GREATEST(",
        "::",
        "IS DISTINCT FROM",
        "ON COMMIT",
        "CAST(:",
        "LATERAL",
        "json_array_elements",
        "#>>",
        "bigint",
        "float8",
        "ANALYZE",
    ),
    "postgresql": (
        "MIN(1.0",
        "MAX(l.",
        "INDEXED BY",
        "INSERT OR",
        "json_extract",
        "json_each(",
        "temp.",
        "CROSS JOIN belief",
        "CROSS JOIN fact",
        " REAL",
        "IS NOT sf",
    ),
}
beliefs_revision = importlib.import_module("toaster.migrations.versions.0003_beliefs")


def _normal(sql: str) -> str:
    return re.sub(r"\s+", " ", sql).strip()


def test_every_step_has_one_template() -> None:
    folder = resources.files("toaster.rules") / "sql"
    names = {p.name for p in folder.iterdir()}
    assert {f"{step}.sql" for step in sqltext.STEPS} <= names
    assert not [n for n in names if n.startswith(("sqlite-", "postgresql-"))]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("step", sqltext.STEPS + sqltext.TRIGGER_TEMPLATES)
def test_every_step_renders_with_known_parameters(step: str, backend: str) -> None:
    sql = sqltext.render(step, backend)
    assert "{{" not in sql and "}}" not in sql
    assert rules._check_sql(sql), sql
    assert "FROM settings" not in sql  # settings are read through belief_settings only
    code = ";".join(pipeline.statements(sql))  # comments left out
    for foreign in FOREIGN[backend]:  # nothing of the other dialect is left
        assert foreign not in code, foreign


def test_both_backends_declare_the_same_macros() -> None:
    assert sqltext.MACROS["sqlite"].keys() == sqltext.MACROS["postgresql"].keys()
    assert not sqltext.COMMON.keys() & sqltext.MACROS["sqlite"].keys()


def test_the_pipeline_runs_every_step_and_only_postgresql_makes_scratch_tables() -> None:
    used = {
        part.name
        for block in pipeline.blocks()
        for part in block.body
        if isinstance(part, pipeline.Step)
    }
    assert used | {"00_temp", "95_materialize", "99_clear"} == set(sqltext.STEPS) | {
        "holders",
        "reperceive",
        "holders_seen",
    }
    assert pipeline.statements(sqltext.render("00_temp", "sqlite")) == []
    assert len(pipeline.statements(sqltext.render("00_temp", "postgresql"))) == 9 + 2


@pytest.mark.slow
def test_the_triggers_of_a_database_at_head_are_the_rendered_ones(db: toaster.Database) -> None:
    """A change of a template or of the pipeline needs a revision that installs the triggers
    again: the database's must be what the package renders."""
    backend = db.engine.dialect.name
    with db.transaction() as conn:
        if backend == "sqlite":
            stored = {
                _normal(row[0])
                for row in conn.execute(
                    text(
                        "SELECT sql FROM sqlite_master WHERE type = 'trigger' "
                        "AND name NOT LIKE '%_guard_%' AND name <> 'agents_holder'"
                    )
                )
            }
        else:
            stored = {
                _normal(row[0])
                for row in conn.execute(
                    text(
                        "SELECT prosrc FROM pg_proc WHERE (left(proname, 13) = 'toaster_step_' OR "
                        "proname IN ('toaster_belief_run', 'toaster_fact_inbox', "
                        "'toaster_settings_changed', 'toaster_agents_changed')) "
                        "AND pronamespace = "
                        "(SELECT oid FROM pg_namespace WHERE nspname = current_schema())"
                    )
                )
            }
    rendered = triggers.ddl(backend)
    if backend == "postgresql":  # the bodies of the functions
        rendered = [r.split("$fn$")[1] for r in rendered if "$fn$" in r]
    assert stored == {_normal(r) for r in rendered}


def test_unknown_or_misused_macros_fail_loudly() -> None:
    with pytest.raises(ValueError, match=r"unknown SQL macro \{\{nope\}\}"):
        sqltext.expand("SELECT {{nope}}", "sqlite")
    with pytest.raises(ValueError, match="takes an argument"):
        sqltext.expand("SELECT {{setting}}", "sqlite")
    with pytest.raises(ValueError, match="takes no argument"):
        sqltext.expand("SELECT {{lo(1)}}", "sqlite")
    with pytest.raises(ValueError, match="unknown backend section"):
        sqltext.expand("{{#mysql}}x{{/mysql}}", "sqlite")
    with pytest.raises(ValueError, match="unrendered"):
        sqltext.expand("SELECT {{lo}", "sqlite")
    with pytest.raises(ValueError, match="unsupported database backend"):
        sqltext.expand("SELECT 1", "mysql")
    with pytest.raises(ValueError, match="unknown belief rule step"):
        sqltext.render("65_nope", "sqlite")


def test_sections_and_arguments() -> None:
    sql = "{{#sqlite}}a{{/sqlite}}{{#postgresql}}b{{/postgresql}} {{as_int8(:t)}} '$' :x"
    assert sqltext.expand(sql, "sqlite") == "a :t '$' :x"
    assert sqltext.expand(sql, "postgresql") == "b CAST(:t AS bigint) '$' :x"
    assert sqltext.expand("{{setting_text(closed)}}", "postgresql") == (
        "(CAST((SELECT value_json FROM belief_settings WHERE key = 'closed') AS json) #>> '{}')"
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_beliefs_revision_froze_the_views_of_the_followed_period(backend: str) -> None:
    """Migration 0003 keeps its own copy of the views (a revision never imports live text):
    it must be what the one followed-period definition renders."""
    frozen = beliefs_revision.views(backend)
    assert [(n, _normal(b)) for n, b in frozen] == [
        (n, _normal(b)) for n, b in sqltext.views(backend)
    ]


@pytest.mark.slow
def test_the_views_of_a_database_at_head_are_the_rendered_ones(db: toaster.Database) -> None:
    """Whatever revision last replaced them, the database's views are :func:`sqltext.views`
    (a change of the followed period needs a revision that replaces them)."""
    backend = db.engine.dialect.name
    with db.transaction(write=True) as conn:
        for name, body in sqltext.views(backend):
            if backend == "sqlite":
                stored = conn.execute(
                    text("SELECT sql FROM sqlite_master WHERE name = :n"), {"n": name}
                ).scalar_one()
                assert _normal(stored) == _normal(f"CREATE VIEW {name} AS {body}")
                continue
            conn.exec_driver_sql(f"CREATE TEMP VIEW check_{name} AS {body}")
            stored, rendered = (
                conn.execute(
                    text("SELECT pg_get_viewdef(CAST(:n AS regclass))"), {"n": n}
                ).scalar_one()
                for n in (name, f"check_{name}")
            )
            assert stored == rendered
            conn.exec_driver_sql(f"DROP VIEW check_{name}")


def test_the_newest_frozen_units_are_the_rendered_ones() -> None:
    """Revisions install frozen units: a change of a template or of the pipeline must come with
    a new revision and its frozen units (python -m toaster.rules.triggers freeze NNNN)."""
    folder = resources.files("toaster.migrations") / "frozen"
    newest = max(p.name for p in folder.iterdir() if p.name.endswith("_units.json"))
    manifest = frozen_triggers.manifest(newest.removesuffix("_units.json"))
    rendered = triggers.units()
    assert list(manifest) == list(rendered)
    for unit, ref in manifest.items():
        frozen = json.loads((folder / ref / f"{unit}.json").read_text(encoding="utf-8"))
        assert frozen == rendered[unit], f"unit {unit} changed: freeze a new revision"


def test_every_frozen_unit_file_is_in_its_revisions_manifest() -> None:
    """A revision's folder holds the units its manifest takes from it, and no others."""
    folder = resources.files("toaster.migrations") / "frozen"
    for path in folder.iterdir():
        if not path.name.endswith("_units.json"):
            continue
        revision = path.name.removesuffix("_units.json")
        own = {unit for unit, ref in frozen_triggers.manifest(revision).items() if ref == revision}
        assert {p.name for p in (folder / revision).iterdir()} == {f"{u}.json" for u in own}


def test_a_step_unit_per_step_instance_and_no_name_shared_with_a_block() -> None:
    units = triggers.step_units()
    assert len(units) == len(
        {
            part
            for block in pipeline.blocks()
            for part in block.body
            if isinstance(part, pipeline.Step)
        }
    )
    assert (
        triggers.unit_name(
            pipeline.Step("20_perceive", (("everything", "1"), ("phase", "'before'")))
        )
        == "20_perceive_1_before"
    )
    assert not {block.name for block in pipeline.blocks()} & set(triggers.units())
    assert all(re.fullmatch(r"\w+", unit) for unit in triggers.units())
