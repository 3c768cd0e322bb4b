"""Fuzzing the library: no value a caller passes to a public function becomes a raw exception.

The CLI checks every argument before it calls the library (tests/cli/test_fuzz.py); a Python
caller, a live producer or a bridge does not. Each case calls one public function of
``toaster.connect``'s database, its store, ``toaster.queries``, ``toaster.beliefs``, ``tell``,
exports and plots with arguments drawn from known trouble (lone surrogates, NUL, 300-byte ids,
times past 2^63 or before 0, floats and text where integers go, NaN) and from hypothesis, and
asserts: it returns, or raises a :class:`~toaster.errors.ToasterError` whose message is one
line, and then the database is exactly as it was (every table's rows compared).

``TOASTER_FUZZ_EXAMPLES=500`` runs a larger campaign than the bounded, reproducible CI one.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import toaster
from tests.cli.test_fuzz import dump
from toaster import Fact, ToasterError
from toaster import queries as q
from toaster.outputs.export import export
from toaster.outputs.plotting import plot_facts

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

EXAMPLES_N = int(os.environ.get("TOASTER_FUZZ_EXAMPLES", "150"))
FUZZ = settings(
    max_examples=EXAMPLES_N,
    deadline=None,
    database=None,
    derandomize="TOASTER_FUZZ_EXAMPLES" not in os.environ,
    suppress_health_check=list(HealthCheck),
)

KNOWN_IDS = ["PR2_ROBOT", "BOB", "ANNE", "MUG", "TABLE", "IsOn", "IsIn", "user", "BOB>ANNE"]
#: text that no id may be, or that means something to SQL, LIKE, shells or toaster itself
BAD_TEXT = [
    "",
    " ",
    "\x00",
    "MUG\x00",
    "\ud800",
    "a\udfffb",
    "x" * 300,
    "é" * 200,
    "NULL",
    "%",
    "_",
    "*",
    "A>B>C",
    "`touch X`",
    "$(touch X)",
    "'; DROP TABLE facts; --",
    '"',
    "\n",
]
NOT_TEXT = [None, 0, 1, -1, 1.5, float("nan"), True, b"MUG", ["MUG"], ("MUG",), {"a": 1}]
BAD_TIMES = [
    -1,
    -(2**63) - 1,
    2**63,
    2**64,
    10**30,
    1.5,
    float("nan"),
    float("inf"),
    "5",
    "5s",
    True,
    None,
    [1],
]
ids = st.one_of(
    st.sampled_from(KNOWN_IDS),
    st.sampled_from(BAD_TEXT),
    st.sampled_from(NOT_TEXT),
    st.text(max_size=12),
)
texts = st.one_of(st.sampled_from(KNOWN_IDS), st.sampled_from(BAD_TEXT), st.text(max_size=12))
times = st.one_of(st.integers(0, 10**11), st.sampled_from(BAD_TIMES), st.integers())
maybe_times = st.one_of(st.none(), times)
numbers = st.one_of(
    st.none(),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(),
    st.sampled_from(["1", "", True, [1.0]]),
)
confidences = st.one_of(st.floats(0, 1), st.sampled_from([-0.1, 1.5, float("nan"), "1", None]))
values = st.one_of(
    st.none(),
    texts,
    numbers,
    st.dictionaries(texts, numbers, max_size=2),
    st.lists(numbers, max_size=2),
)


@st.composite
def facts(draw: st.DrawFn) -> Any:
    fact = Fact(
        draw(ids),
        draw(ids),
        draw(st.one_of(ids, st.just(""))),
        value_text=draw(st.one_of(st.just("true"), texts)),
        value_num=draw(numbers),
        confidence=draw(confidences),
    )
    return draw(
        st.one_of(
            st.just(fact),
            st.sampled_from([("MUG",), ("MUG", "IsOn", "TABLE"), "MUG IsOn TABLE", None]),
        )
    )


fact_lists = st.lists(facts(), max_size=3)


def _calls(tmp: Path) -> dict[str, Callable[[toaster.Database, st.DataObject], Any]]:
    """Public functions, each with its arguments drawn from ``data``."""

    def d(data: st.DataObject, strategy: st.SearchStrategy[Any]) -> Any:
        return data.draw(strategy)

    def out(data: st.DataObject, suffix: str) -> Path:
        return tmp / f"out{d(data, st.integers(0, 3))}.{suffix}"

    return {
        # the store (the write path)
        "add_entity": lambda db, x: db.store().add_entity(
            d(x, ids),
            d(x, st.sampled_from(["object", "human", "robot", "", "x" * 300, None])),
            d(x, st.one_of(texts, st.just(""))),
            d(x, st.one_of(ids, st.just(""))),
            t_ns=d(x, maybe_times),
        ),
        "add_entities": lambda db, x: db.store().add_entities(
            [(d(x, ids), "human", "", "", d(x, st.sampled_from([None, True, "yes"])))],
            t_ns=d(x, maybe_times),
        ),
        "remove_entity": lambda db, x: db.store().remove_entity(d(x, ids)),
        "set_self": lambda db, x: db.store().set_self(d(x, ids), d(x, st.booleans())),
        "sync_snapshot": lambda db, x: db.store().sync_snapshot(
            d(x, ids), d(x, ids), d(x, times), d(x, fact_lists)
        ),
        "sync_many": lambda db, x: db.store().sync_many(
            d(x, ids), d(x, times), [(d(x, ids), d(x, fact_lists))]
        ),
        "assert_fact": lambda db, x: db.store().assert_fact(
            d(x, ids),
            d(x, facts()),
            t_ns=d(x, maybe_times),
            source=d(x, ids),
            strict=d(x, st.booleans()),
            actor=d(x, st.one_of(st.none(), ids)),
        ),
        "retract_facts": lambda db, x: db.store().retract_facts(
            d(x, ids),
            d(x, ids),
            d(x, st.one_of(st.none(), ids)),
            d(x, st.one_of(st.none(), ids)),
            t_ns=d(x, maybe_times),
            source=d(x, ids),
        ),
        "record_event": lambda db, x: db.store().record_event(
            d(x, ids), d(x, facts()), t_ns=d(x, maybe_times), source=d(x, ids)
        ),
        "empty": lambda db, x: db.store().empty(d(x, st.one_of(st.none(), ids))),
        "add_ontology": lambda db, x: db.store().add_ontology(
            d(x, ids), d(x, ids), d(x, st.one_of(st.booleans(), texts))
        ),
        "remove_ontology": lambda db, x: db.store().remove_ontology(
            d(x, ids), d(x, st.one_of(st.none(), ids))
        ),
        "set_property": lambda db, x: db.store().set_property(d(x, ids), d(x, ids), d(x, values)),
        "remove_property": lambda db, x: db.store().remove_property(
            d(x, ids), d(x, st.one_of(st.none(), ids))
        ),
        "put_area": lambda db, x: db.store().put_area(
            d(x, ids),
            d(x, st.one_of(values, st.just({"shape": "circle", "center": [0, 0], "radius": 1}))),
            d(x, st.one_of(ids, st.just(""))),
        ),
        "remove_area": lambda db, x: db.store().remove_area(d(x, ids)),
        "put_setting": lambda db, x: db.store().put_setting(
            d(x, st.one_of(ids, st.just("tolerance"))), d(x, ids), d(x, values)
        ),
        "get_setting": lambda db, x: db.store().get_setting(d(x, ids), d(x, ids)),
        "check_agent": lambda db, x: db.store().check_agent(d(x, ids)),
        "acting": lambda db, x: _acting(
            db,
            d(x, st.one_of(st.none(), ids)),
            d(
                x,
                st.one_of(
                    st.none(),
                    st.dictionaries(st.just(("MUG", "IsOn", "TABLE", "", "", "")), ids, max_size=1),
                ),
            ),
            d(x, fact_lists),
        ),
        "time_frame": lambda db, x: db.time_frame(d(x, st.one_of(texts, st.just("elapsed")))),
        # the read path
        "current_facts": lambda db, x: q.current_facts(
            db,
            d(x, st.one_of(st.none(), ids, st.lists(ids, max_size=2))),
            subject=d(x, st.one_of(st.none(), ids)),
            limit=d(x, st.one_of(st.none(), times)),
        ),
        "memory": lambda db, x: q.memory(
            db,
            d(x, st.one_of(st.none(), ids)),
            since=d(x, maybe_times),
            until=d(x, maybe_times),
            property=d(x, st.one_of(st.none(), ids)),
        ),
        "history": lambda db, x: q.history(
            db,
            d(x, st.one_of(st.none(), ids)),
            since=d(x, maybe_times),
            until=d(x, maybe_times),
            target=d(x, st.one_of(st.none(), ids)),
        ),
        "beliefs_at": lambda db, x: q.beliefs_at(
            db, d(x, ids), d(x, times), subject=d(x, st.one_of(st.none(), ids))
        ),
        "signal": lambda db, x: q.signal(
            db, d(x, st.one_of(st.none(), ids)), since=d(x, maybe_times), until=d(x, maybe_times)
        ),
        "fact_value": lambda db, x: q.fact_value(
            db,
            d(x, ids),
            d(x, ids),
            d(x, ids),
            d(x, st.one_of(ids, st.just(""))),
            at=d(x, maybe_times),
        ),
        "events": lambda db, x: q.events(
            db,
            d(x, st.one_of(st.none(), ids)),
            since=d(x, maybe_times),
            until=d(x, maybe_times),
            kind=d(x, st.one_of(st.none(), ids)),
            limit=d(x, st.one_of(st.none(), times)),
        ),
        "entities": lambda db, x: q.entities(
            db, d(x, st.one_of(st.none(), ids)), kind=d(x, st.one_of(st.none(), ids))
        ),
        "agents": lambda db, x: q.agents(db),
        "ontology": lambda db, x: q.ontology(db, d(x, st.one_of(st.none(), ids))),
        "descendants": lambda db, x: q.descendants(db, d(x, ids)),
        "properties": lambda db, x: q.properties(
            db, d(x, st.one_of(st.none(), ids)), d(x, st.one_of(st.none(), ids))
        ),
        "are_in_table": lambda db, x: q.are_in_table(db, d(x, ids), d(x, fact_lists)),
        "watch": lambda db, x: list(
            q.watch(
                db,
                agent=d(x, st.one_of(st.none(), ids)),
                after_id=d(x, st.one_of(st.none(), times)),
                timeout_s=0.0,
            )
        ),
        "execute": lambda db, x: q.execute(
            db,
            d(
                x,
                st.sampled_from(
                    ["SELECT :a AS a", "SELECT * FROM facts WHERE key_id = :a", "SELECT 1"]
                ),
            ),
            {"a": d(x, values)},
            max_rows=d(x, st.one_of(st.just(10), times)),
            timeout_s=d(x, st.one_of(st.just(5.0), numbers)),
        ),
        # beliefs
        "beliefs": lambda db, x: toaster.beliefs.beliefs(
            db, d(x, ids), d(x, st.one_of(st.none(), ids)), at=d(x, maybe_times)
        ),
        "belief_value": lambda db, x: toaster.belief_value(
            db,
            d(x, ids),
            d(x, ids),
            d(x, ids),
            d(x, st.one_of(ids, st.just(""))),
            at=d(x, maybe_times),
        ),
        "false_beliefs": lambda db, x: toaster.false_beliefs(
            db, d(x, ids), d(x, st.one_of(st.none(), ids)), at=d(x, maybe_times)
        ),
        "belief_history": lambda db, x: toaster.belief_history(
            db,
            d(x, ids),
            d(x, ids),
            d(x, st.one_of(st.none(), ids)),
            agents=d(x, st.one_of(st.none(), st.lists(ids, max_size=2))),
        ),
        "configure": lambda db, x: toaster.beliefs.configure(
            db, **{d(x, st.sampled_from(["share_rows", "copresence", "bogus"])): d(x, values)}
        ),
        "reset": lambda db, x: toaster.beliefs.reset(db, d(x, texts)),
        "tell": lambda db, x: toaster.tell(
            db,
            d(x, ids),
            d(x, facts()),
            listeners=d(x, st.one_of(st.none(), st.lists(ids, max_size=2))),
            t_ns=d(x, maybe_times),
        ),
        # files
        "export": lambda db, x: export(
            db,
            d(x, st.sampled_from(["history", "events", "x"])),
            out(x, d(x, st.sampled_from(["csv", "jsonl"]))),
            agent=d(x, st.one_of(st.none(), ids)),
            since=d(x, maybe_times),
            subject=d(x, st.one_of(st.none(), ids)),
        ),
        "plot_facts": lambda db, x: plot_facts(
            db,
            out(x, "dat"),
            subject=d(x, st.one_of(st.none(), ids)),
            agents=d(x, st.one_of(st.none(), ids)),
            since=d(x, maybe_times),
            until=d(x, maybe_times),
        ),
    }


def _acting(db: toaster.Database, actor: Any, actors: Any, facts: list[Any]) -> None:
    with db.store().acting(actor, actors):
        db.store().sync_snapshot("acted", "PR2_ROBOT", 3_000_000_000, facts)


def seed(db: toaster.Database) -> None:
    """A small world: a robot, two humans, objects, a few facts, events and beliefs."""
    store = db.store()
    store.add_entity("PR2_ROBOT", "robot", is_self=True, t_ns=0)
    for human in ("BOB", "ANNE"):
        store.add_entity(human, "human", t_ns=0)
    for thing in ("MUG", "TABLE"):
        store.add_entity(thing, "object", t_ns=0)
    store.sync_snapshot(
        "seed",
        "PR2_ROBOT",
        1_000_000_000,
        [Fact("MUG", "IsOn", "TABLE"), Fact("BOB", "Distance", "MUG", value_num=1.5)],
    )
    store.assert_fact("BOB", Fact("MUG", "IsOn", "TABLE"), t_ns=2_000_000_000)


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgresql)])
def seeded(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path / 'fuzz.db'}"
        with toaster.connect(url) as db:
            seed(db)
        yield url
        return
    from tests.conftest import pg_schema

    with pg_schema(migrated=True) as url:
        with toaster.connect(url) as db:
            seed(db)
        yield url


@FUZZ
@given(data=st.data())
def test_public_functions_raise_only_one_line_toaster_errors(
    seeded: str, tmp_path: Path, data: st.DataObject
) -> None:
    calls = _calls(tmp_path)
    name = data.draw(st.sampled_from(sorted(calls)), label="function")
    with toaster.connect(seeded) as db:
        before = dump(seeded)
        try:
            calls[name](db, data)
        except ToasterError as exc:
            message = str(exc)
            assert message.strip(), f"{name}: empty message"
            assert "\n" not in message, f"{name}: message of several lines: {message!r}"
            assert dump(seeded) == before, f"{name} failed with {message!r} but wrote"


def _insert(db: toaster.Database, sql: str, **params: object) -> None:
    with db.transaction(write=True) as conn:
        conn.execute(sa.text(sql), params)


#: each finding of issue 24's item 4, and neighbours found by the campaign above
FINDINGS: list[tuple[str, Callable[[toaster.Database], Any]]] = [
    ("entity at 2^63 ns", lambda db: db.store().add_entity("X", "object", t_ns=2**63)),
    ("entity before 0", lambda db: db.store().add_entity("X", "object", t_ns=-1)),
    (
        "retract a lone surrogate",
        lambda db: db.store().retract_facts("PR2_ROBOT", "IsOn", "\ud800"),
    ),
    (
        "a schema constraint in a caller's transaction",
        lambda db: _insert(
            db,
            "INSERT INTO ontology (entity_class, individual, instantiated) "
            "VALUES ('', 'MUG', false)",
        ),
    ),
    (
        "a time past 2^63 in a caller's transaction",
        lambda db: _insert(db, "UPDATE facts SET valid_to_ns = :t", t=2**63),
    ),
    ("query a lone surrogate", lambda db: q.current_facts(db, "PR2_ROBOT", subject="\ud800")),
    ("memory of a lone surrogate", lambda db: q.memory(db, "\ud800")),
    ("events since 2^70", lambda db: q.events(db, since=2**70)),
    ("beliefs at 2^64", lambda db: toaster.beliefs.beliefs(db, "PR2_ROBOT", at=2**64)),
    ("property NaN", lambda db: db.store().set_property("MUG", "weight", float("nan"))),
]


@pytest.mark.parametrize(("what", "call"), FINDINGS, ids=[f[0] for f in FINDINGS])
def test_issue_24_item_4_is_refused_in_one_line(
    seeded: str, what: str, call: Callable[[toaster.Database], Any]
) -> None:
    with toaster.connect(seeded) as db:
        before = dump(seeded)
        with pytest.raises(ToasterError) as caught:
            call(db)
        assert "\n" not in str(caught.value)
        assert dump(seeded) == before
