"""A live node: sources in, producers ticked at a rate, the store written once per tick,
outputs published, control changes applied between ticks (``toaster serve``).

One tick, at the perception time (:mod:`toaster.node.stamps`): apply the control plane if its
version moved (areas, monitored agents, streams, held objects, commands), let every source
apply its newest poses, register entities seen for the first time, compute the producers and
write all their snapshots in one transaction, publish the facts, answer pending queries from
the world as it is now. The loop never queues input (sources keep the newest pose per entity),
counts overruns, and stops between two ticks when asked (SIGINT/SIGTERM in :func:`serve`): the
last tick is committed whole or not at all. While :meth:`LiveNode.run` runs, each tick's write
goes to a writer thread (:mod:`toaster.node.writer`) and the next tick computes meanwhile. A
restart on the same database carries on (entities, areas, control state, open intervals). No
error inside a tick stops the node: :mod:`toaster.node.faults` says what happens instead.
"""

from __future__ import annotations

import gc
import logging
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from toaster.db import catalog
from toaster.db.engine import is_memory
from toaster.db.maintenance import Maintainer
from toaster.errors import ToasterError
from toaster.model import shown
from toaster.node import control, requests
from toaster.node.control_watch import ControlWatch
from toaster.node.faults import GAP_SOURCE, RECONNECT_KINDS, Faults
from toaster.node.output import Output, publish_to
from toaster.node.pacing import TickBudget, wait_for_tick
from toaster.node.stamps import TickClock
from toaster.node.stats import LiveStats
from toaster.node.writer import Pending, TickWriter
from toaster.producers.areas import AreaManager
from toaster.producers.batch import FactBatch, TickFacts
from toaster.producers.monitor import AgentMonitor
from toaster.producers.registry import builtin_producers
from toaster.producers.runner import (
    DEFAULT_SELF,
    MAINTAIN_EVERY_S,
    Runner,
    Source,
    entity_row,
)
from toaster.timeutil import now_ns
from toaster.world.config import make_config
from toaster.world.drops import Drops
from toaster.world.live import LiveSource
from toaster.world.state import World

if TYPE_CHECKING:
    from toaster.db.database import Database

log = logging.getLogger("toaster.node")
#: the periodic status lines (``toaster serve`` shows them at INFO)
status_log = logging.getLogger("toaster.node.status")


#: the page cache of the node's SQLite connections, KiB: a scene of tens of entities ticks as
#: fast with 2 MB as with the engine's 64 MB, which a day of input would fill (docs/live.md)
LIVE_PAGE_CACHE_KIB = 2000

#: a tick is at its newest pose's stamp if at most this old (s), else on the wall clock (stamps.py)
MAX_STAMP_LAG_S = 1.0
#: a service waits at most this long for the writes of the ticks before it (read-your-writes)
FLUSH_WAIT_S = 5.0


class LiveNode:
    """World, producers, store and control plane of one running toaster."""

    def __init__(
        self,
        db: Database | None,
        *,
        config: Mapping[str, Any] | None = None,
        self_id: str = DEFAULT_SELF,
        holders: str | Sequence[str] = "none",
        sources: Sequence[Source] | None = None,
        outputs: Sequence[Output] = (),
        stamp: str = "perception",
    ) -> None:
        self.db = db
        if db is not None:
            db.set_page_cache(LIVE_PAGE_CACHE_KIB)
        self.store = db.store() if db is not None else None
        self.config = make_config(config)
        self.self_id = self_id
        self.holders = holders
        self.world = World()
        self.drops = Drops()  # inputs refused at the edge, per topic and field
        self.api = LiveSource("api", drops=self.drops)
        # entities placed with set_entity_pose are simulated, as toaster_simu publishes them:
        # their pose is sent again every tick until moved or removed
        self.simu = LiveSource("toaster_simu", drops=self.drops)
        self._simulated: dict[str, dict[str, Any]] = {}
        self.sources: list[Source] = [self.simu, *(sources if sources is not None else [self.api])]
        self.outputs = list(outputs)
        self.producers: list[Any] = builtin_producers(
            self.config, {}, spatial=bool(self.config.get("spatial")), live=True
        )
        # the control plane changes these two: areas, and which agents are monitored
        self.areas = next(p for p in self.producers if isinstance(p, AreaManager))
        self.monitor = next(p for p in self.producers if isinstance(p, AgentMonitor))
        self.runner = Runner(
            self.world, [], self.producers, store=self.store, agent_id=self_id, config=self.config
        )
        self.stats = LiveStats()
        self._warn_lock = threading.Lock()
        self.faults = Faults(self.warn)
        self.clock = TickClock(stamp, MAX_STAMP_LAG_S, self.warn)  # each tick's time
        self._version = -1
        self._last_t = 0
        self.wake = threading.Event()  # set by sources when a pose arrives
        self._woken_at = 0.0  # when it was set (monotonic s)
        self._queries_waiting = False
        self._watch: ControlWatch | None = None  # while run() runs on PostgreSQL
        # while run() runs: the writer thread, and the node thread's own connection for reads
        self._writer: TickWriter | None = None
        self._reads: Database | None = None
        self._registered: set[str] = set()
        self._carry: list[tuple[str, str, str, str, bool | None]] = []  # to register again
        self._hands: dict[str, tuple[str, str]] = {}
        self._default_monitored = self.config["monitored_agents"]
        for source in self.sources:
            source.setup(self.world)
        if self.store is not None:
            self._load()

    # -- start-up -------------------------------------------------------------------------------
    def _load(self) -> None:
        """Register the self agent and read back what the database holds (a restart)."""
        store, db = self.store, self.db
        assert store is not None
        assert db is not None
        store.add_entity(self.self_id, "robot", is_self=True)
        with db.transaction() as conn:
            rows = conn.exec_driver_sql(
                "SELECT id, kind, name, owner_id FROM entities ORDER BY owner_id <> '', id"
            ).all()
        for entity_id, kind, name, owner in rows:
            if kind in ("human", "robot", "object") or (kind == "joint" and owner):
                try:
                    self.world.add_entity(
                        entity_id,
                        kind,
                        owner_id=owner if kind == "joint" else "",
                        name=name or entity_id,
                    )
                except ToasterError as exc:
                    self.warn(f"entity {entity_id!r} from the database ignored: {exc}")
                    continue
                self.world.active[self.world.row(entity_id)] = False  # until it is seen
                self._registered.add(entity_id)

    # -- connections ---------------------------------------------------------------------------
    @property
    def read_db(self) -> Database:
        """The handle this (the node's) thread reads with: its own connection while the
        writer thread runs (which owns the store's), else the store's."""
        assert self.db is not None
        return self._reads if self._reads is not None else self.db

    @contextmanager
    def exclusive(self) -> Iterator[None]:
        """Use the store's connection on the node's thread: while the writer runs, after the
        ticks handed to it (read-your-writes) and with it kept out (node/writer.py)."""
        if self._writer is None:
            yield
            return
        with self._writer.idle(FLUSH_WAIT_S, unless=lambda: self.faults.failing):
            yield

    def flush_writes(self, timeout_s: float = FLUSH_WAIT_S) -> bool:
        """Wait until the ticks computed so far are stored (or failed: not during an
        outage), at most ``timeout_s``; for a reader on another connection (a ROS service)
        that must see them. True if they are (also when there is no writer)."""
        if self._writer is None:
            return True
        return self._writer.flush(timeout_s, unless=lambda: self.faults.failing)

    # -- control plane -------------------------------------------------------------------------
    def apply_control(self, t_ns: int | None = None) -> bool:
        """Apply the control plane if it changed since the last look; True if it did.
        Commands take effect at ``t_ns`` (default: now)."""
        if self.db is None or (self._watch is not None and not self._watch.due()):
            return False
        with self.read_db.transaction() as conn:  # every tick (PostgreSQL: on a NOTIFY)
            if catalog.control_version(conn) == self._version:
                return False
        with self.exclusive(), self.db.transaction(write=True) as conn:  # commands answered
            version = catalog.control_version(conn)
            state = control.read_state(conn)
            stored_areas = catalog.areas(conn)
            commands = control.pending(conn, control.COMMANDS)
            self._queries_waiting = True  # a new query also moved the version
            for command in commands:
                try:
                    self._command(command, now_ns() if t_ns is None else t_ns)
                    control.finish(conn, command.id, "ok")
                except (ToasterError, KeyError, TypeError, ValueError, ArithmeticError) as exc:
                    self.warn(f"command {command.kind} {shown(command.args)} refused: {exc}")
                    control.finish(conn, command.id, error=str(exc))
                self.stats.commands += 1
        self._version = version  # committed: a failed transaction is read again next tick
        self._apply_state(state, stored_areas)
        return True

    def _apply_state(
        self, state: control.ControlState, stored_areas: dict[str, dict[str, Any]]
    ) -> None:
        current = self.areas.areas
        for area_id in set(current) - set(stored_areas):
            self.areas.remove_area(area_id)
        for area_id, spec in stored_areas.items():
            if area_id not in current or current[area_id] != spec:
                try:
                    self.areas.set_area(area_id, spec)
                except ToasterError as exc:
                    self.warn(f"area {area_id!r} ignored: {exc}")
        agents = state.monitored_agents(self._default_monitored)
        if isinstance(agents, list) and state.excluded:
            agents = agents + [f"-{a}" for a in state.excluded]
        self.monitor.config["monitored_agents"] = agents
        self.monitor.config["monitored_joints"] = state.joints
        for name, on in state.streams.items():
            self.world.set_source_enabled(name, on)
        for obj in set(self._hands) - set(state.in_hand):
            if obj in self.world.index:
                self.world.remove_from_hand(obj)
        for obj, (agent, joint) in state.in_hand.items():
            try:
                self.world.put_in_hand(obj, agent, joint)
            except ToasterError as exc:
                self.warn(f"put_in_hand {obj!r} -> {agent}/{joint} waits: {exc}")
                continue
        self._hands = dict(state.in_hand)

    def _command(self, command: control.Command, t_ns: int) -> None:
        requests.command(self, command, t_ns)

    def answer_queries(self) -> int:
        """Answer pending on-request queries from the world as it is now (looked for only
        after the control version moved: a query bumps it)."""
        if self.db is None or not self._queries_waiting:
            return 0
        with self.exclusive(), self.db.transaction(write=True) as conn:
            queries = control.pending(conn, control.QUERIES)
            for query in queries:
                try:
                    control.finish(conn, query.id, self.query(query.kind, query.args))
                except (ToasterError, KeyError, TypeError, ValueError, ArithmeticError) as exc:
                    control.finish(conn, query.id, error=str(exc))
        self._queries_waiting = False  # answered and committed (else: again next tick)
        return len(queries)

    def query(self, kind: str, args: Mapping[str, Any]) -> Any:
        """One on-request query (the original's services) against the current world."""
        return requests.query(self, kind, args)

    # -- ticks ----------------------------------------------------------------------------------
    def warn(self, line: str) -> None:
        """One warning line (logged, counted); the node keeps running."""
        with self._warn_lock:  # from the node's and the writer's threads
            self.stats.warnings += 1
        log.warning("%s", line)

    def _new_rows(self) -> list[tuple[str, str, str, str, bool | None]]:
        """Entities seen for the first time, as rows to register (with the tick's write)."""
        world = self.world
        new = [
            r for r, eid in enumerate(world.ids) if eid not in self._registered and world.active[r]
        ]
        self._registered.update(world.ids[r] for r in new)
        return [entity_row(world, r, self.holders) for r in new]

    def tick(self, t_ns: int | None = None) -> TickFacts:
        """One tick at ``t_ns`` (default: the perception time, :mod:`toaster.node.stamps`);
        returns the facts per producer (Fact tuples built when read), none when the tick was
        not stored. It never raises: a failed tick is rolled back and handled as
        :mod:`toaster.node.faults` says. While :meth:`run` runs, the write is handed to the
        writer thread and the facts are returned (and published) before it."""
        now = self.clock.now(self.sources, self.world) if t_ns is None else t_ns
        t = max(now, self._last_t + 1)  # time only moves on
        self._last_t = t
        writer = self._writer
        if writer is not None:
            writer.begin()  # a reader that flushes once its fact lists went out waits for it
        try:
            pending = self._compute(t)
        except Exception as exc:  # contained: see toaster.node.faults
            if writer is not None:
                writer.abandon()
            self._failed(exc, t)
            return TickFacts({})
        if writer is not None:
            if writer.submit(pending):
                self.stats.coalesced += 1
        elif not self._store(pending):
            return TickFacts({})
        self._publish(t, pending.facts, "publish")
        try:
            self.answer_queries()
        except Exception as exc:
            if self._writer is None:  # as a failed tick (the queries are answered again)
                self._failed(exc, t)
                return TickFacts({})
            self._read_failed("answering queries", exc)
        return pending.facts

    def _failed(self, exc: Exception, t: int) -> None:
        """A tick not stored (on the thread whose connection failed: the writer's, or the
        node's without a writer)."""
        if self.faults.tick_failed(exc, t) in RECONNECT_KINDS:
            if self._writer is not None and threading.current_thread() is not self._writer.thread:
                if self._reads is not None:  # the node's thread: its own connection
                    self._reads.reset_connection()
                return
            self._reconnect()

    def _compute(self, t: int) -> Pending:
        """The node thread's part of a tick: control plane, sources, producers, fact lists."""
        self._control(t)
        for entity_id, pose in self._simulated.items():
            self.simu.push(entity_id, t_ns=t, **pose)
        for source in self.sources:
            try:
                source.advance(self.world, t)
            except ToasterError as exc:  # a source's bad batch loses that batch only
                self.warn(f"source {getattr(source, 'name', '?')}: {exc}")
            take = getattr(source, "take_warnings", None)
            for line in take() if take is not None else ():
                self.warn(f"source {getattr(source, 'name', '?')}: {line}")
        for line in self.drops.take_lines():
            self.warn(line)
        # what arrived so far is applied: only poses arriving from now on call for a tick (not
        # those pushed while the sources advanced, e.g. /tf mapped on this thread)
        self.wake.clear()
        register = self._new_rows() if self.store is not None else []
        out = self.runner.compute(t, on_error=self._producer_failed)
        for batch in out.values():  # the writer builds their facts after the world moved on
            if isinstance(batch, FactBatch):
                batch.pin()
        facts = TickFacts(out)
        self._publish(t, facts, "publish_facts")  # before the write: the fact lists go
        for name in out:
            self.faults.part_worked(f"producer {name}")
        return Pending(t, out, self.runner.hands.movers, facts, register)

    def _control(self, t: int) -> None:
        """Apply the control plane. Without a writer a failure fails the tick (as before);
        with one, the tick goes on (its fact lists go out), the control plane is read again
        at the next tick, and not at all during an outage (the writer meets it)."""
        if self._writer is None:
            self.apply_control(t)
            return
        if self.faults.failing:
            return
        try:
            self.apply_control(t)
        except Exception as exc:
            self._read_failed("reading the control plane", exc)
        else:
            self.faults.part_worked("reading the control plane")

    def _read_failed(self, what: str, exc: Exception) -> None:
        """A database error on the node's thread while the writer runs: logged once (the
        next tick tries again); a lost connection is dropped."""
        effect = "tried again at the next tick"
        if self.faults.noted(what, exc, effect) in RECONNECT_KINDS and self._reads is not None:
            self._reads.reset_connection()

    def _store(self, pending: Pending) -> bool:
        """Write one computed tick (on the writer thread while :meth:`run` runs); True if it
        was stored. A failure is handled as :mod:`toaster.node.faults` says; the entities it
        would have registered are registered with the next tick."""
        store = self.store
        t = pending.t_ns
        register, self._carry = self._carry + pending.register, []
        try:
            if store is not None:
                if register:
                    with store.transaction():
                        for entity_id, kind, name, owner, agent in register:
                            store.add_entity(
                                entity_id, kind, name=name, owner_id=owner, agent=agent, t_ns=t
                            )
                self.runner.write(t, pending.out, pending.movers)
        except Exception as exc:  # contained: see toaster.node.faults
            self._carry = register
            self._failed(exc, t)
            return False
        self.runner.stats.ticks += 1
        self.faults.tick_stored(t)
        if self.faults.pending:
            self._record_gaps()
        with self._warn_lock:
            self.stats.ticks += 1
        return True

    def _publish(self, t: int, facts: TickFacts, method: str) -> None:
        """Every output's ``method`` (those that have it); an output failing does not stop
        the node."""
        publish_to(self.outputs, method, t, facts, self.world, self.faults)

    def _producer_failed(self, name: str, exc: Exception) -> None:
        self.faults.part_failed(f"producer {name}", exc)

    def _record_gaps(self) -> None:
        """Store the events of the gaps healed (kept for a later tick if that fails)."""
        if self.store is None:
            self.faults.pending.clear()
            return
        for gap in list(self.faults.pending):
            try:
                self.store.record_event(
                    self.self_id, gap.fact(self.self_id), t_ns=gap.start_ns, source=GAP_SOURCE
                )
            except Exception as exc:
                effect = "it is recorded at a later tick"
                if self.faults.noted("recording a gap", exc, effect) in RECONNECT_KINDS:
                    self._reconnect()
                return
            self.faults.recorded(gap)
        self.faults.part_worked("recording a gap")

    def _reconnect(self) -> None:
        """Drop a connection that may be dead (the next tick connects again) and what the
        store remembers of the database."""
        if self.db is None:
            return
        self.db.reset_connection()
        if self.store is not None:
            self.store.forget()

    def run(
        self,
        rate_hz: float = 30.0,
        *,
        stop: threading.Event | None = None,
        ticks: int | None = None,
        seconds: float | None = None,
        maintain_every_s: float | None = MAINTAIN_EVERY_S,
        status_every_s: float = 0.0,
    ) -> LiveStats:
        """Tick until ``stop`` is set (or ``ticks`` / ``seconds`` ran out).

        Ticks follow the input: a tick starts as soon as a source received a pose, within a
        budget of ticks (:mod:`toaster.node.pacing`: at most 1.25 × ``rate_hz`` a second on
        average, two in a row at once), and without input ``IDLE_WAIT`` periods after the
        previous one. A tick that takes longer than
        the period counts as an overrun; the next one may start at once (no burst of catch-up
        ticks). After a tick that failed on a database fault the next attempt waits for the
        backoff (:mod:`toaster.node.faults`), or for ``stop``.
        Every ``maintain_every_s`` seconds the database is maintained on a thread and
        connection of its own (:mod:`toaster.db.maintenance`), never between two ticks, where
        it stalled the node. Every ``status_every_s`` seconds (0: never) a status line is
        logged and given to the outputs that have a ``status`` method.
        """
        if rate_hz <= 0:
            msg = f"rate {rate_hz} must be a positive number of ticks per second"
            raise ValueError(msg)
        period = 1.0 / rate_hz
        stop = stop or threading.Event()
        for source in self.sources:  # not toaster_simu: it re-sends its poses every tick
            if hasattr(source, "on_push") and source is not self.simu:
                source.on_push = self._woken
        # what exists now lives as long as the node: keep it out of the collector's full
        # passes, which otherwise stalled a tick (docs/live.md)
        gc.collect()
        gc.freeze()
        maintainer = None
        if self.db is not None and maintain_every_s is not None:
            maintainer = Maintainer(self.db, maintain_every_s).start()
        self._watch = ControlWatch.of(self.db)
        try:
            with self.writing():
                self._loop(period, stop, ticks, seconds, status_every_s)
        finally:
            if maintainer is not None:
                maintainer.stop()
            if self._watch is not None:
                self._watch.stop()
                self._watch = None
        return self.stats

    @contextmanager
    def writing(self) -> Iterator[None]:
        """Ticks inside are written on a writer thread (:meth:`run` ticks inside), and the
        node's thread reads on a connection of its own; at the end the tick that waits is
        stored (not during an outage: it is dropped, as a tick that fails) and the writer
        ends. An in-memory SQLite database has one connection: its ticks are written in turn.
        """
        db = self.db
        if db is None or is_memory(db.engine.url) or self._writer is not None:
            yield
            return
        from toaster.db.database import Database
        from toaster.db.engine import make_engine

        # An engine of its own: resetting a lost connection disposes its handle's pool, which
        # on a shared engine would orphan the other thread's connection (closed only by GC).
        reads = self._reads = Database(make_engine(db.url), db.url)
        reads.set_page_cache(LIVE_PAGE_CACHE_KIB)
        writer = self._writer = TickWriter(self._store, lambda: self.faults.delay)
        try:
            yield
        finally:
            writer.close(drain=not self.faults.failing)
            self._writer = self._reads = None
            reads.close()

    def _loop(
        self,
        period: float,
        stop: threading.Event,
        ticks: int | None,
        seconds: float | None,
        status_every_s: float,
    ) -> None:
        begin = last_status = time.monotonic()
        self.stats.started = self.stats.window_start = begin
        budget = TickBudget(period, begin)
        count = 0
        while not stop.is_set():
            if ticks is not None and count >= ticks:
                break
            if seconds is not None and time.monotonic() - begin >= seconds:
                break
            start = time.monotonic()
            budget.take(start)
            if self.wake.is_set():  # input waited for this tick since it came
                self.stats.record_wait((start - self._woken_at) * 1e3)
            self.tick()
            count += 1
            now = time.monotonic()
            if status_every_s > 0 and now - last_status >= status_every_s:
                self.report_status()
                last_status = now
            if self._writer is None and self.faults.delay:  # a database fault: the backoff
                stop.wait(self.faults.delay)  # (with a writer, the writer waits for it)
                continue
            if not self.faults.failing:
                self._record(time.monotonic() - start, period)
            wait_for_tick(start, period, stop, self.wake, budget)

    def status(self, *, window: bool = False) -> str:
        """The status line (:meth:`LiveStats.line`) with this node's dropped messages."""
        return self.stats.line(self.drops.summary(), window=window)

    def report_status(self) -> str:
        """Log a windowed status line and hand it to the outputs that publish it."""
        line = self.status(window=True)
        status_log.info("%s", line)
        for output in self.outputs:
            publish = getattr(output, "status", None)
            if publish is not None:
                try:
                    publish(line)
                except Exception as exc:  # an output failing must not stop the node
                    self.warn(f"output {type(output).__name__} status: {exc}")
        return line

    def _woken(self) -> None:
        if not self.wake.is_set():  # cheaper than setting it for every pose of a message
            self._woken_at = time.monotonic()
            self.wake.set()

    def _record(self, took: float, period: float) -> None:
        ms = took * 1e3
        self.stats.record(ms, took > period)
        n = self.stats.overruns
        if took > period and (n in (1, 10, 100) or n % 1000 == 0):
            self.warn(
                f"tick overran its period: {ms:.1f} ms > {period * 1e3:.1f} ms "
                f"({n} overruns so far)"
            )


__all__ = ["LiveNode", "LiveStats", "Output"]
