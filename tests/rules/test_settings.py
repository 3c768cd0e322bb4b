"""Belief settings: one set of defaults, declared by the database and read alike by Python and
by the rule statements, so that a missing ``settings`` row means the default everywhere."""

from __future__ import annotations

import importlib
import json
from importlib import resources

import pytest
import sqlalchemy as sa

import toaster
from toaster.beliefs import api, scenario
from toaster.errors import InvalidInputError
from toaster.rules import settings as cfg

revision = importlib.import_module("toaster.migrations.versions.0011_holder_groups")

SALLY_ANNE = resources.files("toaster") / "examples" / "beliefs_sally_anne.yaml"
#: A value other than the default for each setting.
OTHER = {
    "enabled": False,
    "depth": 1,
    "copresence": ["IsNear"],
    "containment": ["IsUnder"],
    "visibility": {"Sees": "subject"},
    "closed": "IsShut",
    "refute_by_target": [],
    "self_perception": True,
    "share_rows": False,
    "attention": {"IsInRoom": ["IsLookingToward"]},
    "trust": "witnesses",
    "distrust": ["ANNE"],
    "group_holders": False,
}


def delete_row(db: toaster.Database, key: str) -> None:
    """What a user of plain SQL does: delete the settings row."""
    with db.transaction(write=True) as conn:
        conn.execute(
            sa.text("DELETE FROM settings WHERE scope = 'beliefs' AND key = :k"), {"k": key}
        )


def marble_beliefs(db: toaster.Database) -> dict[str, set[str]]:
    scenario.replay(db, SALLY_ANNE)
    at = 4_000_000_000  # Sally out of the room, the marble moved to the box
    return {
        holder: {
            r.target_id
            for r in api.beliefs(db, holder, property="IsIn", at=at)
            if r.subject_id == "MARBLE"
        }
        for holder in ("SALLY", "ANNE")
    }


def test_every_setting_has_a_kind_and_a_database_default(db: toaster.Database) -> None:
    assert set(OTHER) == set(cfg.KINDS)
    assert api.config(db) == revision.DEFAULTS  # nothing stored: the database's defaults


@pytest.mark.slow
@pytest.mark.parametrize("key", sorted(OTHER))
def test_a_deleted_setting_row_means_the_default(db: toaster.Database, key: str) -> None:
    default = api.config(db)[key]
    assert api.configure(db, **{key: OTHER[key]})[key] == OTHER[key]
    delete_row(db, key)
    assert api.config(db)[key] == default
    with db.transaction() as conn:  # the rule statements read the same view
        stored = conn.execute(
            sa.text("SELECT value_json FROM belief_settings WHERE key = :k"), {"k": key}
        ).scalar_one()
    assert json.loads(stored) == default


@pytest.mark.slow
def test_room_rule_behaves_as_default_once_its_row_is_deleted(db: toaster.Database) -> None:
    """The reported bug: deleting the copresence row left the SQL without a room property
    (nobody learnt anything) while ``beliefs config`` showed the default. With the default
    rule, at 4 s Sally (out of the room) keeps the basket and Anne (in it) saw the box."""
    api.configure(db, copresence=["IsNear"])
    delete_row(db, "copresence")
    assert marble_beliefs(db) == {"SALLY": {"BASKET"}, "ANNE": {"BOX"}}


@pytest.mark.slow
def test_reset_puts_settings_back_and_rejects_unknown_keys(db: toaster.Database) -> None:
    api.configure(db, depth=1, share_rows=False)
    assert api.reset(db, "depth")["depth"] == revision.DEFAULTS["depth"]
    assert api.config(db)["share_rows"] is False
    assert api.reset(db) == revision.DEFAULTS
    with pytest.raises(InvalidInputError, match="unknown beliefs setting 'nope'"):
        api.reset(db, "nope")
