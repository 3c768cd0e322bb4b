"""A run that publishes (``toaster run --foxglove`` / ``--ros2``): :class:`RunNode`, the node
that ``toaster serve``'s outputs are started on, for a run of a file.

The outputs of a live node (the Foxglove server, the ROS 2 bridge) read their node's self
agent, areas, counters and database, and are handed each tick's facts. A :class:`RunNode` has
those, from the run's session and runner: the same outputs, started the same way
(``start_server(node, port)``, ``start_bridge(node)``), publish each of the run's ticks as
they publish a live one (:func:`toaster.node.output.publish_to`): the fact lists as soon as the
producers computed the tick, the rest once its write is handed to the writer thread. What a
run does not have is left out: inputs a bridge adds (a run's input is its file) are not read,
and the services that change a live node (areas, monitors, poses) are not offered. The stamps
are the run's own (the facts' times in the database); each tick's time is first told to
``clocks`` (Foxglove's server time, ROS 2's /clock), so that viewers follow the run's clock.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from toaster.node.faults import Faults
from toaster.node.output import publish_to
from toaster.node.stats import LiveStats
from toaster.producers.areas import AreaManager
from toaster.producers.batch import TickFacts
from toaster.world.drops import Drops

if TYPE_CHECKING:
    from toaster.db import Database
    from toaster.producers import Runner, Session

log = logging.getLogger("toaster.run")
#: how often :meth:`RunNode.wait_for_subscriber` looks (s)
WAIT_POLL_S = 0.05


class RunNode:
    """What a live node's outputs read of their node, for one run (:func:`toaster.app.runs.
    run_file` calls :meth:`computed` and :meth:`ticked` each tick; :meth:`close` at the end)."""

    def __init__(self, db: Database | None, session: Session, runner: Runner) -> None:
        self.db = db
        self.self_id = session.self_id
        self.world = session.world
        self.producers = session.producers
        self.runner = runner
        found = [p for p in session.producers if isinstance(p, AreaManager)]
        self.areas = found[0] if found else AreaManager(session.areas, session.config)
        self.stats = LiveStats()
        self.drops = Drops()
        self.faults = Faults(self.warn)
        self.outputs: list[Any] = []
        self.sources: list[Any] = []  # a bridge's inputs: not read (the input is the file)
        #: told each tick's time before its outputs (a server's clock)
        self.clocks: list[Callable[[int], None]] = []
        #: whether someone subscribes to an output (:meth:`wait_for_subscriber`)
        self.listeners: list[Callable[[], bool]] = []
        self._reads: Database | None = None
        self._facts: Mapping[str, Any] = TickFacts({})
        self._work = 0.0
        self._began = 0.0
        self._warn_lock = threading.Lock()

    @property
    def read_db(self) -> Database:
        """The handle the run's thread reads with: a connection of its own (the writer
        thread writes on the store's), or the store's for an in-memory database (the run then
        writes each tick before the next: :attr:`write_behind`)."""
        assert self.db is not None
        if self._reads is None:
            if not self.write_behind:
                return self.db
            from toaster.db.database import Database
            from toaster.db.engine import make_engine

            self._reads = Database(make_engine(self.db.url), self.db.url)
        return self._reads

    @property
    def write_behind(self) -> bool:
        """Whether a tick may be written while the next computes (not on an in-memory
        database: one connection)."""
        from toaster.db.engine import is_memory

        return self.db is None or not is_memory(self.db.engine.url)

    def warn(self, line: str) -> None:
        """One warning line (logged, counted); the run goes on."""
        with self._warn_lock:
            self.stats.warnings += 1
        log.warning("%s", line)

    def status(self, *, window: bool = False) -> str:
        """The status line, as a live node's."""
        return self.stats.line(self.drops.summary(), window=window)

    def flush_writes(self, timeout_s: float = 0.0) -> bool:
        """Nothing to wait for: a run's outputs offer no service that writes."""
        return True

    def wait_for_subscriber(self, stop: threading.Event) -> bool:
        """Wait until one of :attr:`listeners` says someone subscribes (True), or ``stop``."""
        while not stop.is_set():
            if any(listened() for listened in self.listeners):
                return True
            stop.wait(WAIT_POLL_S)
        return False

    def computed(self, t_ns: int, out: Mapping[str, Any]) -> None:
        """A tick's producers are computed: its time to the clocks, its fact lists out."""
        work = sum(s for name, s in self.runner.stats.seconds.items() if name != "store")
        self._began = time.monotonic() - (work - self._work)
        self._work = work
        for clock in self.clocks:
            try:
                clock(t_ns)
            except Exception as exc:
                self.faults.part_failed("clock", exc, "the outputs go on")
        self._facts = TickFacts(out)
        publish_to(self.outputs, "publish_facts", t_ns, self._facts, self.world, self.faults)

    def ticked(self, t_ns: int) -> None:
        """A tick's write is handed over: the rest of its outputs."""
        publish_to(self.outputs, "publish", t_ns, self._facts, self.world, self.faults)
        self.stats.ticks += 1
        self.stats.record((time.monotonic() - self._began) * 1e3, False)

    def close(self) -> None:
        """Close the run's own read connection."""
        if self._reads is not None:
            self._reads.close()
            self._reads = None
