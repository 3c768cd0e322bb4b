"""``Runner.run_at`` writes tick k on a thread while tick k+1 computes: it must store what
ticking one by one stores, every tick in order, and stop cleanly on an error."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import pytest

import toaster
from tests.conftest import pg_schema
from toaster.model import Fact
from toaster.producers import Runner, load_session
from toaster.queries import events, history

EXAMPLE = Path(toaster.__file__).parent / "examples" / "scenario_spatial_sally_anne.yaml"


def _timeline(db: object) -> tuple[list[tuple[object, ...]], list[tuple[object, ...]]]:
    """Every interval (without the wall-clock time it was recorded) and every event, sorted
    (rows tied on time come in the order of their ids, which a retried transaction shifts)."""
    facts = sorted(
        (tuple(row._replace(recorded_ns=0)) for row in history(db)),  # type: ignore[arg-type]
        key=repr,
    )
    said = sorted(
        (tuple(e._replace(id=0, recorded_ns=0)) for e in events(db)),  # type: ignore[arg-type]
        key=repr,
    )
    return facts, said


def _runner(url: str) -> tuple[object, Runner, object]:
    db = toaster.connect(url)
    store = db.store()
    session = load_session(EXAMPLE)
    runner = Runner(
        session.world, session.sources, session.producers, store=store, agent_id=session.self_id
    )
    session.register(store)
    return db, runner, session


def test_a_pipelined_run_stores_what_ticking_one_by_one_stores(db_url: str, tmp_path: Path) -> None:
    with ExitStack() as stack:
        if db_url.startswith("sqlite"):
            other = f"sqlite:///{tmp_path / 'one_by_one.db'}"
        else:
            other = stack.enter_context(pg_schema(migrated=True))
        one_by_one, runner, session = _runner(other)
        step = round(1e9 / session.rate_hz)
        for t in range(session.start_ns, session.end_ns + 1, step):
            runner.tick(t)
        reference = _timeline(one_by_one)
        one_by_one.close()  # type: ignore[attr-defined]
    pipelined, runner, session = _runner(db_url)
    runner.run(session.start_ns, session.end_ns, session.rate_hz)
    try:
        facts, said = _timeline(pipelined)
        assert facts and said  # beliefs, false ones included, and events were stored
        assert set(facts) ^ set(reference[0]) == set()
        assert set(said) ^ set(reference[1]) == set()
        assert (facts, said) == reference  # the same rows, as many times
    finally:
        pipelined.close()  # type: ignore[attr-defined]


class _FailsAt:
    """A producer that says the tick's time (a new fact each tick) and raises at one tick
    (a bug in a user's producer)."""

    name = "fails"

    def __init__(self, at_ns: int) -> None:
        self.at_ns = at_ns

    def compute(self, world: object, t_ns: int) -> list[Fact]:
        if t_ns == self.at_ns:
            msg = f"broken at {t_ns}"
            raise RuntimeError(msg)
        return [Fact("CLOCK", "IsAt", value_text=str(t_ns))]


def test_an_error_stops_the_run_with_every_tick_before_it_stored(db_url: str) -> None:
    db, runner, session = _runner(db_url)
    step = round(1e9 / session.rate_hz)
    times = list(range(session.start_ns, session.end_ns + 1, step))
    broken = times[len(times) // 2]
    runner.producers.append(_FailsAt(broken))  # type: ignore[arg-type]
    try:
        with pytest.raises(RuntimeError, match=f"broken at {broken}"):
            runner.run_at(times)
        stored = [int(row.value_text) for row in history(db, subject="CLOCK")]  # type: ignore[arg-type]
        # every tick before the failing one is stored (the last was in flight), in order
        assert stored == times[: times.index(broken)]
        assert runner.stats.ticks == times.index(broken)
    finally:
        db.close()
