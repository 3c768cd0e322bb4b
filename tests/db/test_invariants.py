"""The temporal invariants (``toaster.db.invariants``, run by ``toaster db check``) find what
a broken writer would leave: overlapping intervals, boundaries without their event, events
without their boundary."""

from __future__ import annotations

import pytest
import sqlalchemy as sa

import toaster
from toaster import Fact
from toaster.db.invariants import violations

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

CUP = Fact("MUG", "IsOn", "TABLE")


def _story(store: toaster.Store) -> int:
    """The robot's mug on the table from 1 to 5, again from 8; BOB watches. Its key id."""
    store.sync_snapshot(
        "pdg", "PR2_ROBOT", 1, [CUP, Fact("BOB", "IsInRoom", "LAB"), Fact("MUG", "IsInRoom", "LAB")]
    )
    store.sync_snapshot(
        "pdg", "PR2_ROBOT", 5, [Fact("BOB", "IsInRoom", "LAB"), Fact("MUG", "IsInRoom", "LAB")]
    )
    store.sync_snapshot(
        "pdg", "PR2_ROBOT", 8, [CUP, Fact("BOB", "IsInRoom", "LAB"), Fact("MUG", "IsInRoom", "LAB")]
    )
    with store.db.transaction() as conn:
        return conn.execute(
            sa.text(
                "SELECT id FROM fact_keys WHERE agent_id = 'PR2_ROBOT' AND subject_id = 'MUG' "
                "AND property = 'IsOn'"
            )
        ).scalar_one()


def _broken(store: toaster.Store, sql: str, **params: object) -> list[str]:
    """``sql`` run with the store's writer role (as a buggy writer would), then the check."""
    with store.transaction() as conn:
        conn.execute(sa.text(sql), params)
    with store.db.transaction() as conn:
        return violations(conn)


def test_a_sound_story_keeps_every_invariant(store: toaster.Store) -> None:
    _story(store)
    with store.db.transaction() as conn:
        assert violations(conn) == []


def test_an_overlapping_interval_is_found(store: toaster.Store) -> None:
    key = _story(store)
    found = _broken(
        store,
        "INSERT INTO facts (key_id, value_text, confidence, observability, "
        "valid_from_ns, valid_to_ns, recorded_ns, source) "
        "VALUES (:k, 'true', 1, 1, 3, 6, 0, 'bug')",
        k=key,
    )
    assert any(line.startswith("overlap: PR2_ROBOT: MUG IsOn TABLE") for line in found)


def test_a_missing_event_is_found(store: toaster.Store) -> None:
    key = _story(store)
    found = _broken(store, "DELETE FROM events WHERE key_id = :k AND kind = 'ended'", k=key)
    assert (
        "missing event: PR2_ROBOT: MUG IsOn TABLE: 1 ended boundary(ies) at 5, "
        "not as many events" in found
    )


def test_an_event_without_boundary_is_found(store: toaster.Store) -> None:
    key = _story(store)
    found = _broken(
        store,
        "INSERT INTO events (key_id, agent_id, kind, stamp_ns, source, "
        "recorded_ns) VALUES (:k, 'PR2_ROBOT', 'ended', 3, 'bug', 0)",
        k=key,
    )
    assert any(
        line.startswith("event without boundary: PR2_ROBOT: MUG IsOn TABLE: 1 ended")
        for line in found
    )


def test_asserted_retracted_and_asserted_again_at_one_time_is_sound(store: toaster.Store) -> None:
    """An empty interval at t, then the fact again from t: its appeared and the merge's ended
    and appeared are all at t. The check left out every ended and appeared at a merge's stamp,
    the empty interval's own appeared too, and reported it missing."""
    store.assert_fact("PR2_ROBOT", CUP, t_ns=1)
    store.retract_facts("PR2_ROBOT", "IsOn", "MUG", None, t_ns=1)
    store.assert_fact("PR2_ROBOT", CUP, t_ns=1)
    with store.db.transaction() as conn:
        key = conn.execute(sa.text("SELECT id FROM fact_keys WHERE subject_id = 'MUG'")).scalar()
        assert [
            tuple(r)
            for r in conn.execute(
                sa.text("SELECT kind, stamp_ns FROM events WHERE key_id = :k ORDER BY id"),
                {"k": key},
            )
        ] == [("appeared", 1), ("ended", 1), ("appeared", 1)]
        assert violations(conn) == []
    # the pair is left out once: one of its events gone is still found
    found = _broken(store, "DELETE FROM events WHERE key_id = :k AND kind = 'ended'", k=key)
    assert (
        "event without boundary: PR2_ROBOT: MUG IsOn TABLE: 2 appeared event(s) at 1, "
        "not as many boundaries" in found
    )
