"""Property-based: random snapshot / assert / retract sequences against an in-memory model.

Checks the interval invariants on both backends: intervals of a key never overlap, at most one
is open, the current facts equal the model's, and every change has exactly one event.
"""

from __future__ import annotations

import itertools
from collections import defaultdict

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import toaster
from toaster import Fact
from toaster import queries as q

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

SUBJECTS = ("A", "B")
PROPS = ("IsOn", "IsNear")
VALUES = ("true", "false", "maybe")
_counter = itertools.count()

facts = st.builds(
    Fact,
    st.sampled_from(SUBJECTS),
    st.sampled_from(PROPS),
    st.sampled_from(("", "T")),
    st.sampled_from(VALUES),
    st.one_of(st.none(), st.sampled_from((0.5, 1.5))),
    st.sampled_from((0.5, 1.0)),
    observability=st.just(1.0),
    property_type=st.just(""),
    sub_property=st.just(""),
    subject_owner_id=st.just(""),
    target_owner_id=st.just(""),
)
operations = st.lists(
    st.one_of(
        st.tuples(st.just("sync"), st.sampled_from(("p1", "p2")), st.lists(facts, max_size=5)),
        st.tuples(st.just("assert"), facts),
        st.tuples(st.just("retract"), st.sampled_from(PROPS), st.sampled_from((*SUBJECTS, None))),
    ),
    max_size=12,
)


def _key(f: Fact) -> tuple[str, ...]:
    return (f.subject_id, f.property, f.target_id)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(ops=operations)
def test_random_sequences_keep_interval_invariants(db: toaster.Database, ops: list) -> None:
    """Store and a plain dict model agree after any sequence of writes."""
    from hypothesis import note

    note(
        "OPS "
        + repr(
            [
                (
                    o[0],
                    o[1],
                    [
                        (
                            f.subject_id,
                            f.property,
                            f.target_id,
                            f.value_text,
                            f.value_num,
                            f.confidence,
                        )
                        for f in o[2]
                    ],
                )
                if o[0] == "sync"
                else (o[0], tuple(o[1])[:6])
                if o[0] == "assert"
                else o
                for o in ops
            ]
        )
    )
    store = db.store()
    agent = f"AG{next(_counter)}"
    store.add_entity(agent, "robot")
    for name in (*SUBJECTS, "T"):
        store.add_entity(name, "object")
    model: dict[tuple[str, ...], Fact] = {}  # what is believed now
    owner: dict[tuple[str, ...], str] = {}  # who opened the current interval of each key
    source_view: dict[str, dict[tuple[str, ...], Fact]] = defaultdict(dict)
    stale: set[str] = set()  # sources that re-read what they hold at their next snapshot
    expected_events = 0
    for t, op in enumerate(ops, start=1):
        if op[0] == "sync":
            _, source, snapshot = op
            if source in stale:  # the open facts this source opened, as they are now
                source_view[source] = {k: f for k, f in model.items() if owner[k] == source}
                stale.discard(source)
            new = {_key(f): f for f in snapshot}
            for key in source_view[source].keys() - new.keys():
                if key in model:  # the source's fact ends, whoever opened it
                    del model[key]
                    expected_events += 1
            for key, fact in new.items():
                held = model.get(key)
                if source_view[source].get(key) == fact:
                    continue
                if held is None or held.value_text != fact.value_text:
                    expected_events += 1
                    owner[key] = source
                model[key] = fact
            source_view[source] = new
            store.sync_snapshot(source, agent, t, snapshot)
        elif op[0] == "assert":
            fact = op[1]
            held = model.get(_key(fact))
            if held is None or held.value_text != fact.value_text:
                expected_events += 1
                owner[_key(fact)] = "user"
            model[_key(fact)] = fact
            store.assert_fact(agent, fact, t_ns=t)
            stale.update(("p1", "p2"))  # user writes make every source re-read (cache epoch)
        else:
            _, prop, subject = op
            ended = [k for k in model if k[1] == prop and (subject is None or k[0] == subject)]
            for key in ended:
                del model[key]
            expected_events += len(ended)
            assert store.retract_facts(agent, prop, subject, t_ns=t) == len(ended)
            stale.update(("p1", "p2"))

    current = {(r.subject_id, r.property, r.target_id): r for r in q.current_facts(db, agent)}
    assert set(current) == set(model)
    for key, row in current.items():
        assert row.value_text == model[key].value_text
        assert row.confidence == model[key].confidence
    by_key = defaultdict(list)
    for row in q.history(db, agent):
        by_key[(row.subject_id, row.property, row.target_id)].append(row)
    for rows in by_key.values():
        rows.sort(key=lambda r: (r.valid_from_ns, r.valid_to_ns is None, r.valid_to_ns or 0))
        assert sum(r.valid_to_ns is None for r in rows) <= 1
        for earlier, later in itertools.pairwise(rows):
            assert earlier.valid_to_ns is not None
            assert earlier.valid_to_ns <= later.valid_from_ns
    assert len(q.events(db, agent)) == expected_events
