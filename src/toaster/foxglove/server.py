"""The Foxglove WebSocket server of a live node (``toaster serve --foxglove``): the channels of
:mod:`toaster.outputs.foxglove` published each tick by :class:`FoxgloveOutput`, the node's
services (:mod:`toaster.foxglove.services`) callable from the Foxglove app.

Threads: the SDK serves clients on threads of its own. On the node's thread the output sends
/toaster/facts as soon as the producers computed a tick, and hands the rest over to its
publisher thread (:mod:`toaster.foxglove.worker`): a snapshot of the world every VIEW_EVERY
ticks (the scene, areas, motion, /tf; none when no channel of them has a subscriber), a read
of beliefs and events when the node stored new events (else every second), the health
message. The publisher reads the database on a connection of its own (an in-memory database
has one: read on the node's thread, as its ticks are written), and sends each holder's
beliefs again every second for clients that connect late.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from typing import Any, NamedTuple

from toaster.foxglove.worker import Publisher
from toaster.model import EventRow, Fact
from toaster.outputs.foxglove import (
    BELIEFS_TOPIC,
    EVENTS_TOPIC,
    FACTS_TOPIC,
    HEALTH_TOPIC,
    Channels,
    beliefs_message,
    facts_json,
    health_message,
)
from toaster.world.state import World

log = logging.getLogger("toaster.foxglove")
#: the scene, areas, motion and /tf go out every VIEW_EVERY ticks (10 Hz at 30 Hz), as the
#: ROS 1 bridge's views; fact lists every tick
VIEW_EVERY = 3
#: beliefs, events and health are re-read and re-sent at least this often, and beliefs and
#: events re-read at most this often when the node stored new events (5 Hz)
READ_EVERY_S, MIN_READ_S = 1.0, 0.2
#: events stamped this long before the newest one sent are looked for again (late commits)
LOOKBACK_NS = 2_000_000_000
DEFAULT_PORT = 8765


class Views(NamedTuple):
    """What the publisher draws the scene, areas, motion and /tf from: a tick's copies."""

    t_ns: int
    world: World
    areas: Mapping[str, Mapping[str, Any]]
    area_facts: list[Fact]
    motion: list[Fact]


class Read(NamedTuple):
    """A read of beliefs and events at ``t_ns`` (``resend``: every holder's beliefs)."""

    t_ns: int
    resend: bool


def _merged(older: Read, newer: Read) -> Read:
    return Read(newer.t_ns, older.resend or newer.resend)


class FoxgloveOutput:
    """A node output (:class:`toaster.node.output.Output`) publishing on ``channels``;
    :meth:`close` ends its publisher thread."""

    def __init__(self, node: Any, channels: Channels) -> None:
        self.node, self.channels = node, channels
        self.ticks = 0
        self._sent = -1
        self._area_facts: list[Fact] = []
        self._motion: list[Fact] = []
        self._events = -1
        self._read_at = 0.0
        self._beliefs: dict[str, list[Any]] = {}
        self._last_event: tuple[int, set[tuple[int, str]]] | None = None
        self.watches: list[tuple[Any, dict[str, str]]] = []
        self._db: Any = None  # the publisher's connection (made by its thread)
        self.inline_reads = node.db is not None and _is_memory(node.db)
        self.publisher = Publisher(self._run, self._failed, self._worked)

    def publish_facts(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None:
        """The self agent's fact lists, as soon as the producers computed them."""
        self._sent = t_ns
        if self.ticks % VIEW_EVERY == 0:  # the next publish draws the views
            self._area_facts = facts.get("area_manager", [])
            self._motion = facts.get("agent_monitor", [])
        if not self.channels.wanted(FACTS_TOPIC):
            return
        put = self.channels.put_json
        for producer, held in facts.items():
            put(FACTS_TOPIC, facts_json(t_ns, self.node.self_id, producer, held), t_ns)

    def publish(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None:
        """The rest of a tick, handed to the publisher: the views every VIEW_EVERY ticks,
        beliefs, events, health."""
        if self._sent != t_ns:
            self.publish_facts(t_ns, facts, world)
        self.ticks += 1
        if (self.ticks - 1) % VIEW_EVERY == 0 and self.channels.views_wanted():
            areas = self.node.areas.areas  # a new dict; specs are replaced, never changed
            views = Views(t_ns, world.snapshot(), areas, self._area_facts, self._motion)
            self.publisher.submit("views", views)
        events = self.node.runner.stats.events
        now = time.monotonic()
        again = now - self._read_at >= READ_EVERY_S
        if again or (events != self._events and now - self._read_at >= MIN_READ_S):
            self._events, self._read_at = events, now
            if self.node.db is not None and self.inline_reads:
                self._read(self.node.read_db, t_ns, resend=again)
            elif self.node.db is not None:
                self.publisher.submit("read", Read(t_ns, again), _merged)
            if again and self.channels.wanted(HEALTH_TOPIC):
                self.health(t_ns, self.node.status())

    def status(self, line: str) -> None:
        """The node's status line, on /toaster/health."""
        self.health(time.time_ns(), line)

    def health(self, t_ns: int, line: str) -> None:
        """/toaster/health (sent by the publisher): the node's counts, its dropped messages
        and the publisher's dropped jobs."""
        dropped = self.node.drops.total + self.publisher.dropped
        self.publisher.submit("health", health_message(t_ns, self.node.stats, dropped, line))

    def close(self) -> None:
        """Send what waits and end the publisher (and its connection)."""
        if self.publisher.close() and self._db is not None:
            self._db.close()
            self._db = None

    # -- the publisher's thread -----------------------------------------------------------------
    def _run(self, kind: str, job: Any) -> None:
        if kind == "views":
            areas = job.areas
            self.channels.frame(job.t_ns, job.world, areas, job.area_facts, job.motion)
        elif kind == "read":
            self._read(self._reads(), job.t_ns, resend=job.resend)
        else:
            self.channels.put(HEALTH_TOPIC, job)

    def _reads(self) -> Any:
        """The publisher's own connection to the node's database."""
        if self._db is None:
            from toaster.db.database import Database
            from toaster.db.engine import make_engine

            url = self.node.db.url
            from toaster.node.live_node import LIVE_PAGE_CACHE_KIB

            self._db = Database(make_engine(url), url)
            self._db.set_page_cache(LIVE_PAGE_CACHE_KIB)
        return self._db

    def _failed(self, kind: str, exc: BaseException) -> None:
        from toaster.node.faults import RECONNECT_KINDS

        what = f"output FoxgloveOutput ({kind})"
        effect = "the node goes on; tried again with the next tick's"
        kind_of = self.node.faults.noted(what, exc, effect)
        if kind_of in RECONNECT_KINDS and kind == "read" and self._db is not None:
            self._db.reset_connection()

    def _worked(self, kind: str) -> None:
        self.node.faults.part_worked(f"output FoxgloveOutput ({kind})")

    def _read(self, db: Any, t_ns: int, *, resend: bool) -> None:
        """Beliefs of every holder (those that changed, all with ``resend``) and new events."""
        from toaster import queries as q

        if self.watches or self.channels.wanted(EVENTS_TOPIC) or self.channels.log.has_sinks():
            self._new_events(db)
        else:  # nobody listens: the events from the next subscription on
            self._last_event = None
        if not self.channels.wanted(BELIEFS_TOPIC):
            self._beliefs = {}
            return
        held: dict[str, list[Any]] = {}
        for row in q.current_facts(db):
            held.setdefault(row.agent_id, []).append(row)
        truth = held.get(self.node.self_id, [])
        for holder, facts in sorted(held.items()):
            if resend or facts != self._beliefs.get(holder):
                is_self = holder == self.node.self_id
                message = beliefs_message(t_ns, holder, facts, truth, is_self=is_self)
                self.channels.put(BELIEFS_TOPIC, message)
        for holder in self._beliefs.keys() - held.keys():  # a holder that believes nothing now
            self.channels.put(BELIEFS_TOPIC, beliefs_message(t_ns, holder, [], truth))
        self._beliefs = held

    def _new_events(self, db: Any) -> None:
        """The events committed since the last read: those stamped up to LOOKBACK_NS before
        the newest seen are read again (a writer may commit an event stamped before the
        node's newest, as `toaster tell` does) and sent unless already sent."""
        from toaster import queries as q

        if self._last_event is None:  # events from now on: the history is in the database
            newest = q.events(db, limit=1, newest_first=True)
            stamp = newest[0].stamp_ns if newest else 0
            since = max(0, stamp - LOOKBACK_NS)
            self._last_event = (stamp, {(e.id, e.agent_id) for e in q.events(db, since=since)})
            return
        stamp, seen = self._last_event
        read = q.events(db, since=max(0, stamp - LOOKBACK_NS))
        for event in read:
            if (event.id, event.agent_id) in seen:
                continue
            self.channels.event(event)
            for channel, patterns in list(self.watches):
                if matches(event, patterns):
                    channel.log(watch_message(event), log_time=event.stamp_ns)
        if read:
            self._last_event = (
                max(stamp, max(e.stamp_ns for e in read)),
                {(e.id, e.agent_id) for e in read},
            )


def _is_memory(db: Any) -> bool:
    from toaster.db.engine import is_memory

    return is_memory(db.engine.url)


def matches(event: EventRow, patterns: Mapping[str, str]) -> bool:
    """Whether ``event`` matches the glob ``patterns`` (agent, subject, property, target)."""
    from fnmatch import fnmatchcase

    fields = {
        "agent": event.agent_id,
        "subject": event.subject_id,
        "property": event.property,
        "target": event.target_id,
    }
    return all(fnmatchcase(fields[k], p) for k, p in patterns.items() if p)


def watch_message(event: EventRow) -> dict[str, Any]:
    from toaster.outputs.foxglove import event_message

    return event_message(event)


class FoxgloveServer:
    """A running server beside a node; :meth:`shutdown` stops it and detaches its output."""

    def __init__(
        self,
        node: Any,
        port: int = DEFAULT_PORT,
        host: str = "127.0.0.1",
        services: bool = True,
        clock: bool = False,
    ) -> None:
        from foxglove.websocket import Capability

        import foxglove
        from toaster.foxglove.services import node_services

        # The SDK's Rust threads forward their log records to Python logging, taking the GIL
        # while they hold a client's lock; a Python thread logging a message holds the GIL
        # while it waits for that lock: a deadlock seen with a slow client (FOXGLOVE_LOG_LEVEL
        # still sets a level to debug with)
        foxglove.set_log_level(logging.CRITICAL)  # CRITICAL: nothing is logged
        self.node = node
        self.context = foxglove.Context()
        self.channels = Channels(self.context)
        self.output = FoxgloveOutput(node, self.channels)
        self.calls, handlers = node_services(self) if services else (None, [])
        capabilities = [Capability.Services] if handlers else []
        if clock:
            capabilities.append(Capability.Time)
        try:
            self.server = foxglove.start_server(
                name="toaster",
                host=host,
                port=port,
                capabilities=capabilities,
                supported_encodings=["json"],
                services=handlers,
                context=self.context,
            )
        except BaseException:
            self.output.close()
            if self.calls is not None:
                self.calls.close()
            raise
        self.port = self.server.port
        node.outputs.append(self.output)

    def shutdown(self) -> None:
        """Stop serving; the node goes on without this output."""
        if self.output in self.node.outputs:
            self.node.outputs.remove(self.output)
        self.output.close()  # what waits goes out first
        self.server.stop()
        if self.calls is not None:
            self.calls.close()


def start_server(
    node: Any,
    port: int = DEFAULT_PORT,
    host: str = "127.0.0.1",
    services: bool = True,
    clock: bool = False,
) -> FoxgloveServer:
    """Serve ``node`` to Foxglove on ``host:port`` (0: a free port; see ``.port``). With
    ``clock`` the server has the protocol's time capability: the app follows the time given to
    ``.server.broadcast_time(t_ns)`` (a run's own clock), not its own."""
    return FoxgloveServer(node, port, host, services, clock)
