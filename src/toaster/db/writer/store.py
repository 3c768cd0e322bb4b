"""The write path: snapshots from sources become validity intervals and events.

A *source* (a producer, a rule, a user) hands :meth:`Store.sync_snapshot` the complete set of
facts it holds true for one agent at time ``t``. The store compares it with what that source
wrote last (kept in memory, so unchanged facts cost nothing), then in one transaction:

* appeared facts open an interval and write an ``appeared`` event;
* a changed symbolic value (``value_text``) closes the interval at ``t``, opens the next one and
  writes a ``changed`` event (with the previous value);
* a numeric value, confidence or observability that moved beyond the property's tolerance
  (:mod:`toaster.db.tolerance`) refreshes the open interval in place and keeps the numbers it
  held until then in ``fact_samples`` (as-of queries read them); a change within the
  tolerance is not written;
* facts missing from the snapshot close their interval at ``t`` and write an ``ended`` event.

Writes that bypass snapshots (user assertions, retractions, EMPTY) bump ``store_state``'s
``cache_epoch``; every store re-reads what its sources hold on its next transaction, so that the
world state re-asserts itself as in the original's EMPTY. Belief rules registered with
:meth:`Store.add_rule` run in the same transaction as the write that triggers them.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from sqlalchemy import Connection, bindparam, text

from toaster.db import catalog, tolerance
from toaster.db.dialects import LATEST_CLOCK, Key
from toaster.db.tolerance import Tolerance
from toaster.db.writer.changes import Actors, Rule, SyncResult, Writes, merged
from toaster.db.writer.changes import ChangeSet as ChangeSet  # where callers found it
from toaster.db.writer.diff import (
    BatchState,
    FactArrays,
    Snapshot,
    SourceState,
    key_of,
    within,
)
from toaster.db.writer.steps import FactSteps, Reads, Sent
from toaster.errors import TimeOrderError
from toaster.model import Fact, check_fact, check_id, fact_key
from toaster.timeutil import check_ns, format_ns, now_ns

_KEY = key_of
_FIRST = operator.itemgetter(0)


#: How far behind the rules' clock a snapshot may be and still be taken for a live writer's
#: lag (written just after the clock, see Store._writes): beyond, it keeps its own time.
LIVE_CLOCK_SKEW_NS = 1_000_000_000

#: Makes a rule for one store (a :class:`~toaster.db.Database` calls each of its factories
#: once, when it makes its store).
RuleFactory = Callable[["Store"], Rule]


@dataclass(eq=False)
class Plan:
    """One source's snapshot in a write: its differences, then its rows."""

    source: str
    state: SourceState
    t_ns: int
    size: int  # facts in the snapshot
    touched: list[tuple[Key, Fact]] = field(default_factory=list)  # stated, changed
    gone: list[tuple[Key, Fact]] = field(default_factory=list)  # held, missing now
    trust_cache: bool = False  # numbers alone moved: refresh without reading back (batches)
    after: list[Callable[[], None]] = field(default_factory=list)  # once written
    writes: Writes | None = None
    resolve: list[tuple[Key, Fact]] = field(default_factory=list)  # compared with the stored
    reads: Reads | None = None


def _stages(plans: list[Plan]) -> list[list[Plan]]:
    """Plans whose reads may go before the writes of the ones before them: a plan reading a
    key an earlier one writes (two sources stating one fact) starts a stage of its own."""
    stages: list[list[Plan]] = [[]]
    written: set[Key] = set()
    last = len(plans) - 1
    for n, plan in enumerate(plans):
        if stages[-1] and plan.resolve and not written.isdisjoint(map(_FIRST, plan.resolve)):
            stages.append([])
            written = set()
        stages[-1].append(plan)
        if n < last:  # what the plans after it may read
            written.update(map(_FIRST, plan.touched))
            written.update(map(_FIRST, plan.gone))
    return stages


class Store(FactSteps):
    """Writes facts, entities and everything else into a :class:`~toaster.db.Database`
    (typed as the :class:`~toaster.db.handle.Handle` it uses)."""

    # ------------------------------------------------------------------ snapshot sync
    def sync_snapshot(
        self,
        source: str,
        agent_id: str,
        t_ns: int,
        facts: Iterable[Fact] | FactArrays,
        *,
        actor: str | None = None,
        actors: Actors | None = None,
    ) -> SyncResult:
        """Make ``source``'s facts for ``agent_id`` at ``t_ns`` exactly ``facts`` (a list of
        facts, or a producer's :class:`~toaster.producers.batch.FactBatch`).

        Only differences with what the source wrote last reach the database, in one
        transaction; numbers that moved less than their tolerance are not differences.
        Facts about entities nobody registered register them (kind ''). A batch is diffed
        as arrays: only its changed facts become tuples. ``actor``: the agent who made the
        changes, if known; ``actors``: who made each change, per fact, over ``actor`` (a
        function of the fact, called for changed and ended facts only, or a mapping fact key
        -> agent id; see :meth:`acting`).
        """
        if actor is not None or actors is not None:
            with self.acting(actor, actors):
                return self.sync_snapshot(source, agent_id, t_ns, facts)
        check_id(source, "source")
        check_ns(t_ns)
        given = _given(facts)
        exact = self._in_tx  # inside a caller's transaction: answers checked as they come

        def write(conn: Connection) -> SyncResult:
            plan = self._plan(conn, source, agent_id, t_ns, given)
            return self._write_plans(conn, agent_id, [plan], exact=exact)[0]

        return self._retrying(write, clock=agent_id if self._may_clock(agent_id) else None)

    def _state(self, conn: Connection, source: str, agent_id: str) -> SourceState:
        state = self._sources.get((source, agent_id))
        if state is None:
            state = SourceState()
            rows = conn.execute(
                text(
                    "SELECT k.id, k.subject_id, k.property, k.target_id, f.value_text, "
                    "f.value_num, "
                    "f.confidence, f.observability, k.property_type, k.sub_property, "
                    "k.subject_owner_id, k.target_owner_id, f.valid_from_ns "
                    "FROM fact_keys k JOIN facts f ON f.key_id = k.id "
                    "WHERE k.agent_id = :a AND f.source = :s AND f.valid_to_ns IS NULL"
                ),
                {"a": agent_id, "s": source},
            ).all()
            for row in rows:
                fact = Fact(*row[1:12])
                key = fact_key(fact)
                state.facts[key] = fact
                self._key_ids[(agent_id, key)] = row[0]
                state.last_t = max(state.last_t, row[12])
            if self._clocked(agent_id):  # stored times may be the clock's, ahead of the source's
                state.last_t = -(2**63)
            self._sources[(source, agent_id)] = state
        return state

    def _begin(self, conn: Connection, source: str, agent_id: str, t_ns: int) -> SourceState:
        """The source's state, after checking the agent and the time order."""
        self.check_agent(agent_id)
        state = self._state(conn, source, agent_id)
        if t_ns < state.last_t:
            msg = (
                f"snapshot of {source!r} for {agent_id!r} at {format_ns(t_ns)} is older than "
                f"its previous one ({format_ns(state.last_t)}): send snapshots in time order"
            )
            raise TimeOrderError(msg)
        return state

    def tolerances(self, conn: Connection | None = None) -> dict[str, Tolerance]:
        """Tolerance per property (``*``: the rest), read once per cache epoch."""
        if self._tolerances is None:
            if conn is None:
                with self.db.transaction() as read_conn:
                    self._tolerances = tolerance.read(read_conn)
            else:
                self._tolerances = tolerance.read(conn)
        return self._tolerances

    def _plan(
        self,
        conn: Connection,
        source: str,
        agent_id: str,
        t_ns: int,
        given: list[Fact] | FactArrays,
    ) -> Plan:
        if isinstance(given, list):
            return self._plan_list(conn, source, agent_id, t_ns, given)
        return self._plan_batch(conn, source, agent_id, t_ns, given)

    def _plan_list(
        self, conn: Connection, source: str, agent_id: str, t_ns: int, given: list[Fact]
    ) -> Plan:
        state = self._begin(conn, source, agent_id, t_ns)
        state.arrays = None
        old = state.facts
        plan = Plan(source, state, t_ns, len(old))
        if given == state.last_list:  # the same facts in the same order: nothing to do
            return plan
        try:
            new = dict(zip(map(_KEY, given), given, strict=True))
        except (TypeError, IndexError):  # not facts, or a key field that is no text: say which
            for fact in given:
                check_fact(fact)
            raise
        plan.size = len(new)
        if new == old:
            state.last_list = given
            return plan
        held_get = old.get
        table = self.tolerances(conn)
        plan.touched = [
            (key, check_fact(fact))
            for key, fact in new.items()
            if (held := held_get(key)) != fact and not within(table, fact, held)
        ]
        plan.gone = [(key, fact) for key, fact in old.items() if key not in new]
        plan.after.append(lambda: setattr(state, "last_list", given))
        return plan

    def _plan_batch(
        self, conn: Connection, source: str, agent_id: str, t_ns: int, batch: FactArrays
    ) -> Plan:
        """A fact batch, diffed as arrays (:mod:`.diff`)."""
        state = self._begin(conn, source, agent_id, t_ns)
        arrays = state.arrays
        if arrays is None or arrays.world is not batch.world:
            plan = self._plan_list(conn, source, agent_id, t_ns, batch.facts())

            def rebuilt() -> None:
                state.last_list = None
                state.arrays = BatchState.of(batch, state.facts)

            plan.after.append(rebuilt)
            return plan
        new = Snapshot.of(batch, self.tolerances(conn))
        touched, keep, old_pos, gone = arrays.diff(new)
        facts = batch.facts_at(new.order[touched])
        if facts and not batch.plain():  # checked as arrays, else one by one (one-line errors)
            facts = [check_fact(f) for f in facts]
        keys = list(map(_KEY, facts))
        plan = Plan(source, state, t_ns, len(new.keys), trust_cache=True)
        plan.touched = list(zip(keys, facts, strict=True))
        held = state.facts
        plan.gone = [(key, held[key]) for key in arrays.gone(gone)]

        def updated() -> None:
            state.last_list = None
            state.arrays = arrays.updated(new, touched, keep, old_pos, keys, gone)

        plan.after.append(updated)
        return plan

    def _rows(self, conn: Connection, agent_id: str, plan: Plan) -> None:
        """The plan's rows: ends; with ``trust_cache``, a fact whose numbers alone moved
        refreshes what this source wrote without reading it back (a refresh that finds no
        open interval means another writer ended it: retry); the rest is compared with the
        open interval, whoever wrote it (``plan.resolve``)."""
        key_ids, old = self._key_ids, plan.state.facts
        # Events in order: ended, changed, appeared.
        named = {x for _, f in (*plan.touched, *plan.gone) for x in (f.subject_id, f.target_id)}
        writes = plan.writes = self._writes(
            conn, agent_id, plan.source, plan.t_ns, snapshot=True, named=named
        )
        for key, fact in plan.gone:
            writes.end(key_ids[(agent_id, key)], fact)
        if plan.trust_cache and plan.touched and self.agents().get(agent_id):
            for key, fact in plan.touched:
                held = old.get(key)
                if held is not None and held[3] == fact[3] and held[7] == fact[7]:
                    writes.refreshed.append((key_ids[(agent_id, key)], fact, held))
                else:
                    plan.resolve.append((key, fact))
        else:
            plan.resolve = plan.touched

    def _write_plans(
        self, conn: Connection, agent_id: str, plans: list[Plan], *, exact: bool
    ) -> list[SyncResult]:
        """Write the plans' differences (of one agent at one time) and run the rules once
        over them: one batch of reads and one of writes (:mod:`.steps`)."""
        active = [plan for plan in plans if plan.touched or plan.gone]
        if active:
            for plan in active:
                self._rows(conn, agent_id, plan)
            if any(plan.resolve for plan in active) and not self.agents().get(agent_id):
                self._detach(conn, agent_id, keep=True)
            self._write_stages(conn, agent_id, _stages(active), exact=exact or self._exact)
        return [self._done(plan) for plan in plans]

    def _write_stages(
        self, conn: Connection, agent_id: str, stages: list[list[Plan]], *, exact: bool
    ) -> None:
        pipelined = self._rules_pipelined()
        sent: list[Sent] = []
        for n, stage in enumerate(stages):
            resolving = [plan for plan in stage if plan.resolve]
            if resolving:
                with self._batch():
                    for plan in resolving:
                        plan.reads = self._send_reads(agent_id, plan.resolve)
                for plan in resolving:
                    assert plan.reads is not None
                    self._take_reads(agent_id, plan.reads, plan.writes)
            with self._batch():
                for plan in stage:
                    assert plan.writes is not None
                    sent.append(self._send_writes(plan.writes, exact=exact))
                if pipelined and n == len(stages) - 1:
                    self._tick_rules(conn, sent)
        for one in sent:
            self._check(one)
        if not pipelined:
            self._tick_rules(conn, sent)
        self._exact = False

    def _tick_rules(self, conn: Connection, sent: list[Sent]) -> None:
        """The rules, once over the changes of all the sources written."""
        for changes in merged([changes for one in sent for changes in one.changes]):
            self._run_rules(conn, changes)

    @staticmethod
    def _done(plan: Plan) -> SyncResult:
        """Remember what the plan wrote; count it."""
        state, writes = plan.state, plan.writes
        if writes is not None:
            old = state.facts
            old.update(plan.touched)
            for key, _ in plan.gone:
                del old[key]
        state.last_t = plan.t_ns
        for step in plan.after:
            step()
        if writes is None:
            return SyncResult(0, 0, 0, 0, plan.size)
        return SyncResult(
            len(writes.appeared),
            len(writes.changed),
            len(writes.refreshed),
            len(writes.ended),
            plan.size - len(plan.touched),
        )

    def _may_clock(self, agent_id: str) -> bool:
        """Whether a snapshot of ``agent_id`` may follow the rules' clock, as far as the
        store remembers (its transaction then reads the clock with the cache epoch)."""
        agents = self._agents
        if not self._rules:
            return False
        return agents is None or (agent_id in agents and not all(agents.values()))

    def _clocked(self, agent_id: str) -> bool:
        """Snapshots of ``agent_id`` follow the rules' clock (see :meth:`_writes`): rules run,
        ``agent_id`` is registered and somebody holds beliefs."""
        agents = self.agents()
        return bool(self._rules) and agent_id in agents and not all(agents.values())

    def _writes(
        self,
        conn: Connection,
        agent_id: str,
        source: str,
        t_ns: int,
        *,
        snapshot: bool = False,
        named: set[str] | None = None,
    ) -> Writes:
        """The rows of one write of ``agent_id`` at ``t_ns``.

        The belief runs follow the rules' clocks (each holder's ``clock_ns``, its last run's
        time, and ``clock_self``, its self agent; a snapshot reads the latest): a write at the
        time of its own robot's
        last run shares that instant, any other run at or before the clock comes 1 ns after it
        (revision 0015: one robot's writes at one time reach the holders at that time, two
        robots' runs never share an instant). A ``snapshot`` behind the clock (before it, or
        at another robot's run) by at most :data:`LIVE_CLOCK_SKEW_NS` (a live robot or
        producer whose clock is a little behind another's, or ticks at the same instant) is
        written 1 ns after it, so that the self rows and the holders' rows that follow them
        share one timeline. A source's later
        snapshots are never written before one so moved: a live robot whose lag grows past
        the skew stays on the clock's timeline instead of failing with a time-order error.
        The sources of one :meth:`sync_many` (a tick) are written at one stamp, the latest any
        of them needs. Older snapshots (one source imported after another) and single writes
        (assert, retract, tell) keep their time: their runs happen at the clock's (or just
        after). The clock is read without a lock: a run locks its own holders' clocks
        (toaster.rules.pipeline.CLOCK), so that runs sharing no holder do not wait for each
        other; a run whose holders' clocks moved meanwhile happens just after them."""
        given = t_ns
        if snapshot and self._in_tick and self._tick_ns is not None:
            t_ns = self._tick_ns  # a later source of the tick: the first one's stamp
        elif snapshot and self._clocked(agent_id):
            clock, self._clock = self._clock, None  # read as the write began
            if clock is None:
                row = conn.execute(text(LATEST_CLOCK), {"agent": agent_id}).first()
                clock = (row[0], row[1]) if row is not None else (None, None)
            if clock[0] is None and named:  # its keys name nobody yet: the snapshot's people
                row = conn.execute(
                    text(
                        "SELECT clock_ns, clock_self FROM holders WHERE depth = 1 "
                        "AND clock_ns IS NOT NULL AND id IN :ids ORDER BY clock_ns DESC LIMIT 1"
                    ).bindparams(bindparam("ids", expanding=True)),
                    {"ids": sorted(named - {""})},
                ).first()
                clock = (row[0], row[1]) if row is not None else clock
            last, last_self = clock
            moved = max(
                self._moved_to.get((agent_id, s), t_ns) for s in (*self._tick_sources, source)
            )
            behind = last is not None and (t_ns < last or (t_ns == last and last_self != agent_id))
            if behind and last is not None and last <= t_ns + LIVE_CLOCK_SKEW_NS:
                t_ns = max(last + 1, moved)
            elif t_ns < moved:
                t_ns = moved if last is None else max(moved, last + 1)
        if snapshot and self._in_tick:
            self._tick_ns = t_ns
        if snapshot and t_ns != given:
            self._moved_to[(agent_id, source)] = t_ns
        return Writes(agent_id, source, t_ns, self._actor, self._actor_of)

    def sync_many(
        self,
        agent_id: str,
        t_ns: int,
        snapshots: Iterable[tuple[str, Iterable[Fact] | FactArrays]],
        *,
        actor: str | None = None,
        actors: Actors | None = None,
    ) -> list[SyncResult]:
        """:meth:`sync_snapshot` of several sources for one agent at one time, in one
        transaction, the rules running once over all their changes (a producer tick).
        ``actor`` and ``actors`` (per fact) name who made the changes, as for
        :meth:`sync_snapshot`."""
        check_ns(t_ns)
        given = [(check_id(source, "source"), _given(facts)) for source, facts in snapshots]
        exact = self._in_tx  # inside a caller's transaction: answers checked as they come

        def write(conn: Connection) -> list[SyncResult]:
            self._in_tick, self._tick_ns = True, None
            self._tick_sources = tuple(source for source, _ in given)
            try:
                plans = [self._plan(conn, source, agent_id, t_ns, facts) for source, facts in given]
                return self._write_plans(conn, agent_id, plans, exact=exact)
            finally:
                self._in_tick, self._tick_ns, self._tick_sources = False, None, ()

        with self.acting(actor, actors):
            return self._retrying(write, clock=agent_id if self._may_clock(agent_id) else None)

    # ------------------------------------------------------------------ single writes
    def assert_fact(
        self,
        agent_id: str,
        fact: Fact,
        *,
        t_ns: int | None = None,
        source: str = "user",
        strict: bool = True,
        actor: str | None = None,
    ) -> str:
        """State one fact for an agent at ``t_ns`` (default now); return what happened
        (``appeared``, ``changed``, ``refreshed`` or ``unchanged``).

        With ``strict`` the subject and target must be registered entities. ``actor``: the
        agent who made the change, if known.
        """
        fact = check_fact(fact)
        t_ns = now_ns() if t_ns is None else check_ns(t_ns)
        with self.acting(actor), self.transaction() as conn:
            self.check_agent(agent_id)
            if strict:
                catalog.check_entities(conn, [fact.subject_id, fact.target_id])
            key = fact_key(fact)
            writes = self._writes(conn, agent_id, source, t_ns)
            self._resolve(conn, agent_id, [(key, fact)], writes)
            self._apply(conn, writes)
            self.bump_epoch(conn)
        return writes.outcome()

    def retract_facts(
        self,
        agent_id: str,
        property: str,
        subject_id: str | None = None,
        target_id: str | None = None,
        *,
        sub_property: str | None = None,
        subject_owner_id: str | None = None,
        target_owner_id: str | None = None,
        t_ns: int | None = None,
        source: str = "user",
        actor: str | None = None,
    ) -> int:
        """End the matching current facts of an agent at ``t_ns`` (default now).

        ``None`` or ``"NULL"`` for subject or target match any (the original's wildcard).
        Returns the number of facts ended. ``actor``: the agent who ended them, if known.
        """
        check_id(property, "property")
        t_ns = now_ns() if t_ns is None else check_ns(t_ns)
        filters = {
            "subject_id": subject_id,
            "target_id": target_id,
            "sub_property": sub_property,
            "subject_owner_id": subject_owner_id,
            "target_owner_id": target_owner_id,
        }
        with self.acting(actor), self.transaction() as conn:
            self.check_agent(agent_id)
            if not self.agents().get(agent_id):
                self._detach(conn, agent_id, keep=True)
            rows = catalog.open_facts_matching(conn, agent_id, property, filters)
            writes = self._writes(conn, agent_id, source, t_ns)
            for key_id, fact, valid_from in rows:
                if valid_from > t_ns:
                    msg = (
                        f"cannot end {fact.subject_id} {fact.property} {fact.target_id} at "
                        f"{format_ns(t_ns)}: it started later, at {format_ns(valid_from)}"
                    )
                    raise TimeOrderError(msg)
                writes.end(key_id, fact)
            self._apply(conn, writes)
            self.bump_epoch(conn)
        return len(rows)

    def record_event(
        self, agent_id: str, fact: Fact, *, t_ns: int | None = None, source: str = "user"
    ) -> None:
        """Record a user event (the original's set_info EVENT) for an agent."""
        fact = check_fact(fact)
        t_ns = now_ns() if t_ns is None else check_ns(t_ns)
        with self.transaction():
            self.check_agent(agent_id)
            key = fact_key(fact)
            self._key_id_map(agent_id, [(key, fact)])
            self.backend.insert_events(
                self.db.cursor(),
                [
                    (
                        self._key_ids[(agent_id, key)],
                        agent_id,
                        "event",
                        t_ns,
                        fact.value_text,
                        fact.value_num,
                        fact.confidence,
                        fact.observability,
                        None,
                        source,
                        now_ns(),
                    )
                ],
            )

    def empty(self, agent_id: str | None = None) -> None:
        """Delete the facts, memory and events of one agent, or of every agent (EMPTY)."""
        with self.transaction() as conn:
            if agent_id is not None:
                self.check_agent(agent_id)
            self._detach(conn, agent_id, keep=False)
            catalog.empty_facts(conn, agent_id)
            self.bump_epoch(conn)


def _given(facts: Iterable[Fact] | FactArrays) -> list[Fact] | FactArrays:
    """A snapshot as a list of facts, or a producer's batch as it is."""
    if isinstance(facts, list):  # the common case first: a protocol check is slower
        return facts
    if isinstance(facts, FactArrays):
        return facts
    return list(facts)
