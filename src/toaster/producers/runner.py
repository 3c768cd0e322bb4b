"""Ticks sources and producers, hands each producer's snapshot to the store, keeps statistics."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Protocol

from toaster.errors import FileFormatError, InvalidInputError
from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.producers.diff import SnapshotDiff
from toaster.producers.perception import HandActors, actors_of
from toaster.producers.registry import Producer, builtin_producers
from toaster.timeutil import NS_PER_S, check_rate
from toaster.world.bags import is_bag, read_bag
from toaster.world.config import make_config, overlay_config
from toaster.world.scenario import ScenarioSource, load_scenario
from toaster.world.state import EntityPose, World
from toaster.world.tracks import read_obsmat, read_tracks

DEFAULT_SELF = "toaster"
#: Wall seconds between two database maintenances of a run (PostgreSQL VACUUM of the hot
#: tables: these machines' server runs without autovacuum, and dead rows piled up; docs/store.md).
MAINTAIN_EVERY_S = 60.0


class Source(Protocol):
    """What the runner needs from a source."""

    name: str

    def setup(self, world: World) -> None: ...

    def advance(self, world: World, t_ns: int) -> None: ...


@dataclass
class Stats:
    """Totals of a run."""

    ticks: int = 0
    facts: int = 0
    appeared: int = 0
    changed: int = 0
    ended: int = 0
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def events(self) -> int:
        """Appearances + value changes + ends."""
        return self.appeared + self.changed + self.ended


class Runner:
    """One world, its sources and producers, and optionally a store to write snapshots to."""

    def __init__(
        self,
        world: World,
        sources: Sequence[Source],
        producers: Sequence[Producer],
        *,
        store: Any = None,
        agent_id: str = DEFAULT_SELF,
        config: Mapping[str, Any] | None = None,
    ) -> None:
        self.world, self.sources, self.producers = world, list(sources), list(producers)
        self.store, self.agent_id = store, agent_id
        self.diff = SnapshotDiff()
        cfg = make_config(config)  # (the thresholds of who moved what)
        self.hands = HandActors(cfg["actor_hand_reach"], cfg["actor_moved"])
        self.stats = Stats()
        for source in self.sources:
            source.setup(world)

    def tick(
        self,
        t_ns: int,
        *,
        on_error: Callable[[str, Exception], None] | None = None,
        computed: Callable[[dict[str, list[Fact] | FactBatch]], None] | None = None,
    ) -> dict[str, list[Fact] | FactBatch]:
        """Advance every source to ``t_ns``, compute every producer, write the snapshots.

        Producers with ``compute_batch`` hand over array snapshots (Fact tuples are only built
        for the store; ``as_facts`` turns a returned batch into tuples). The changes of where
        a held object is are written as made by the agent holding it (:class:`HandActors`).
        With ``on_error``, a producer that raises is left out of the tick (its stored facts
        stay as they were) and ``on_error(name, exc)`` is told; without, the error propagates.
        ``computed(out)`` is called once every producer is computed, before the write (a live
        node publishes the fact lists then).
        """
        out = self.compute(t_ns, on_error=on_error)
        if computed is not None:
            computed(out)
        if self.store is not None:
            self.write(t_ns, out, self.hands.movers)
        self.stats.ticks += 1
        return out

    def compute(
        self, t_ns: int, *, on_error: Callable[[str, Exception], None] | None = None
    ) -> dict[str, list[Fact] | FactBatch]:
        """The computing half of :meth:`tick`: sources, world, producers, no write."""
        clock = time.perf_counter
        start = clock()
        for source in self.sources:
            source.advance(self.world, t_ns)
        self.world.commit()
        self.hands.update(self.world)
        self._add("world", clock() - start)
        out: dict[str, list[Fact] | FactBatch] = {}
        for producer in self.producers:
            start = clock()
            batch = getattr(producer, "compute_batch", None)
            try:
                facts = batch(self.world, t_ns) if batch else producer.compute(self.world, t_ns)
            except Exception as exc:
                if on_error is None:
                    raise
                on_error(producer.name, exc)
                continue
            self._add(producer.name, clock() - start)
            out[producer.name] = facts
            start = clock()
            changes = self.diff.apply(producer.name, facts)
            self._add("diff", clock() - start)
            self.stats.facts += len(facts)
            self.stats.appeared += changes.appeared
            self.stats.changed += changes.changed
            self.stats.ended += changes.ended
        return out

    def write(
        self, t_ns: int, out: Mapping[str, list[Fact] | FactBatch], movers: Mapping[str, str]
    ) -> None:
        """The writing half of :meth:`tick`: all producers' snapshots in one transaction (one
        commit per tick, the belief rules run once over all of them); fact batches go to the
        store as they are (diffed as arrays there). ``movers``: the tick's
        :attr:`HandActors.movers`. A tick is all or nothing: the store retries it whole when
        it conflicts with a concurrent writer. A live node calls it on its writer thread."""
        start = time.perf_counter()
        store, agent = self.store, self.agent_id
        actors = actors_of(movers, store.agents()) if movers else None
        store.sync_many(agent, t_ns, list(out.items()), actors=actors)
        self._add("store", time.perf_counter() - start)

    def _add(self, name: str, seconds: float) -> None:
        self.stats.seconds[name] = self.stats.seconds.get(name, 0.0) + seconds

    def run(
        self,
        start_ns: int,
        end_ns: int,
        rate_hz: float,
        *,
        realtime: bool = False,
        on_tick: Callable[[int], None] | None = None,
        maintain_every_s: float | None = MAINTAIN_EVERY_S,
    ) -> Stats:
        """Tick from start to end (inclusive) at ``rate_hz`` (:meth:`run_at` on that grid)."""
        step = round(NS_PER_S / check_rate(rate_hz))
        return self.run_at(
            range(start_ns, end_ns + 1, step),
            realtime=realtime,
            on_tick=on_tick,
            maintain_every_s=maintain_every_s,
        )

    def run_at(
        self,
        times: Iterable[int],
        *,
        realtime: bool = False,
        on_tick: Callable[[int], None] | None = None,
        maintain_every_s: float | None = MAINTAIN_EVERY_S,
        computed: Callable[[int, dict[str, list[Fact] | FactBatch]], None] | None = None,
        stop: threading.Event | None = None,
        write_behind: bool = True,
    ) -> Stats:
        """Tick at ``times`` (ns, increasing); pace them to the clock from the first if
        ``realtime``; stop between two ticks once ``stop`` is set.

        ``computed(t_ns, out)`` is called once a tick's producers are computed, before its
        write (a run that publishes sends the tick then). ``write_behind`` False writes each
        tick before the next computes (one connection: an in-memory SQLite database that the
        caller also reads). Every ``maintain_every_s`` seconds of wall time the database is
        maintained between two ticks (:meth:`toaster.db.Database.maintain`: PostgreSQL
        vacuums the hot tables).
        """
        wall0 = last_maintained = time.monotonic()
        first: int | None = None
        stop = stop or threading.Event()
        with _Pipeline(self, computed, write_behind=write_behind) as pipeline:
            for t in times:
                first = t if first is None else first
                if realtime:
                    delay = (t - first) / NS_PER_S - (time.monotonic() - wall0)
                    if delay > 0:
                        stop.wait(delay)
                if stop.is_set():
                    break
                pipeline.tick(t)
                if on_tick is not None:
                    on_tick(t)
                now = time.monotonic()
                if (
                    self.store is not None
                    and maintain_every_s is not None
                    and now - last_maintained >= maintain_every_s
                ):
                    pipeline.wait()
                    self.store.db.maintain()
                    last_maintained = time.monotonic()
                    self._add("maintain", last_maintained - now)
        return self.stats


class _Pipeline:
    """Ticks of :meth:`Runner.run_at` with tick k written on a thread while tick k+1
    computes (the database releases the interpreter while it works): one write in flight,
    every tick written, in order; a write's error is raised before the next write (the
    ticks computed after it write nothing). Without a store, plain ticks."""

    def __init__(
        self,
        runner: Runner,
        computed: Callable[[int, dict[str, list[Fact] | FactBatch]], None] | None = None,
        *,
        write_behind: bool = True,
    ) -> None:
        self.runner, self.computed, self.write_behind = runner, computed, write_behind
        self._pool: ThreadPoolExecutor | None = None
        self._writing: Future[None] | None = None

    def __enter__(self) -> _Pipeline:
        if self.runner.store is not None and self.write_behind:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="toaster-write")
        return self

    def tick(self, t_ns: int) -> None:
        runner, computed = self.runner, self.computed
        if self._pool is None:
            runner.tick(t_ns, computed=None if computed is None else partial(computed, t_ns))
            return
        out = runner.compute(t_ns)
        for batch in out.values():  # their facts are built on the thread, the world moves on
            if isinstance(batch, FactBatch):
                batch.pin()
        if computed is not None:
            computed(t_ns, out)
        movers = dict(runner.hands.movers)
        self.wait()
        self._writing = self._pool.submit(runner.write, t_ns, out, movers)
        runner.stats.ticks += 1

    def wait(self) -> None:
        """Wait for the write in flight (raising its error)."""
        writing, self._writing = self._writing, None
        if writing is not None:
            writing.result()

    def __exit__(self, kind: object, error: object, trace: object) -> None:
        try:
            if kind is None:
                self.wait()
            elif self._writing is not None:  # the write in flight ends; the first error wins
                self._writing.exception()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)


@dataclass
class Session:
    """Everything ``toaster run`` needs from an input file."""

    world: World
    sources: list[Source]
    producers: list[Producer]
    areas: dict[str, dict[str, Any]]
    self_id: str
    start_ns: int
    end_ns: int
    rate_hz: float
    config: dict[str, Any]
    #: which humans hold beliefs (become store agents): "none", "humans" or their ids
    belief_holders: str | tuple[str, ...] = "humans"
    #: agents get their per-agent views when registered (scenarios); recordings, with
    #: thousands of people, register theirs without (``toaster db views`` makes them)
    agent_views: bool = True

    def frame(self, t_ns: int, *, with_areas: bool = False) -> tuple[Any, ...]:
        """A recording frame of the world now (:mod:`toaster.outputs.recording`): every entity the
        producers see (perceived; agents within ``presence_timeout``, as pdg publishes them) as
        an ``EntityPose`` (full pose, size, joints with their agent, held objects with their
        hand, perception time), and every area's spec ``(id, spec)`` when asked."""
        import numpy as np

        from toaster.world.config import ns

        world, ids = self.world, self.world.ids
        timeout = ns(make_config(self.config), "presence_timeout")

        def pose(r: int) -> EntityPose:
            owner, hand = int(world.owner[r]), int(world.held_by[r])
            x, y, z = (float(v) for v in world.pos[r])
            roll, pitch, yaw = (float(v) for v in world.rpy[r])
            sx, sy, sz = (float(v) for v in world.size[r])
            return EntityPose(
                ids[r],
                world.kind_text[r],
                x,
                y,
                z,
                yaw,
                roll,
                pitch,
                (sx, sy, sz) if np.isfinite(world.size[r]).all() else None,
                ids[owner] if owner >= 0 else "",
                world.names[r],
                ids[hand] if hand >= 0 else "",
                int(world.t_ns[r]),
            )

        live = np.flatnonzero(world.live_mask(t_ns, timeout)).tolist()
        areas = [(area_id, dict(spec)) for area_id, spec in self.areas.items()]
        return (t_ns, [pose(r) for r in live], areas if with_areas else None)

    def register(self, store: Any) -> None:
        """Put the areas and entities in the store before the first tick (the self agent as a
        self robot, joints with their owner), and record the input's start as the data's
        start (:meth:`toaster.db.Store.register_start`), in one transaction, as ``toaster
        run`` does.

        Humans become agents (belief holders) only as ``belief_holders`` says; the others are
        plain entities. Other robots stay agents, as the store makes them by default.
        """
        world, start, holders = self.world, self.start_ns, self.belief_holders
        rows = sorted(
            entity_row(world, row, holders)
            for row, entity_id in enumerate(world.ids)
            if entity_id != self.self_id
        )  # (one order for every process)

        def register(conn: Any) -> None:
            store.register_start(start)  # first: before the writes that lock store_state
            for area_id, spec in sorted(self.areas.items()):
                store.put_area(area_id, spec, spec.get("owner", ""))
            store.add_entity(self.self_id, "robot", is_self=True, t_ns=start)
            store.add_entities(rows, t_ns=start, views=self.agent_views)

        store.retried(register)


def entity_row(
    world: World, row: int, holders: str | Sequence[str]
) -> tuple[str, str, str, str, bool | None]:
    """A world row as the store's ``(id, kind, name, owner_id, agent)`` (joints with their
    owner); a human is an agent (a belief holder) only as ``holders`` ("none", "humans" or
    ids) says."""
    entity_id, kind = world.ids[row], world.kind_text[row]
    owner = world.ids[world.owner[row]] if world.owner[row] >= 0 else ""
    agent = None
    if kind == "human":
        agent = holders == "humans" or (not isinstance(holders, str) and entity_id in holders)
    return entity_id, kind, world.names[row], owner, agent


def register_row(
    store: Any, world: World, row: int, holders: str | Sequence[str], t_ns: int
) -> None:
    """Put a world row in the store as an entity (see :func:`entity_row`)."""
    entity_id, kind, name, owner, agent = entity_row(world, row, holders)
    store.add_entity(entity_id, kind, name=name, owner_id=owner, agent=agent, t_ns=t_ns)


def _belief_holders(value: Any, kinds: dict[str, str], name: str) -> str | tuple[str, ...]:
    """Normalise a belief-holders choice: "none", "humans", or ids (a list or "a,b")."""
    if isinstance(value, str):
        word = value.strip()
        if word.lower() in ("none", "humans"):
            return word.lower()
        value = word.split(",")
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        msg = (
            f"belief holders {value!r} for {name}: give none, humans or a list of ids "
            "(--holders ID[,ID...])"
        )
        raise InvalidInputError(msg)
    ids = tuple(dict.fromkeys(v.strip() for v in value if v.strip()))
    sample = ",".join([i for i, kind in kinds.items() if kind == "human"][:3]) or "(none)"
    if not ids:
        msg = f"no belief holders given for {name}: give none, humans or ids such as {sample}"
        raise InvalidInputError(msg)
    for entity_id in ids:
        if kinds.get(entity_id) not in ("human", "robot"):
            msg = (
                f"belief holder {entity_id!r} is not a human of {name}: give none, humans "
                f"or ids of its people, such as {sample}"
            )
            raise InvalidInputError(msg)
    return ids


def load_session(
    path: str | Path,
    areas: dict[str, dict[str, Any]] | None = None,
    *,
    fps: float | None = None,
    holders: str | Sequence[str] | None = None,
    config: Mapping[str, Any] | None = None,
    tf_map: str | Path | None = None,
    pose_topics: Mapping[str, tuple[str, str]] | None = None,
) -> Session:
    """Build world, sources and producers from a scenario (.yaml/.yml/.json) or recording.

    Recordings: ``obsmat.txt`` (ETH/UCY; frame numbers at ``fps``, default 25, checked against
    the annotated velocities; ticks at the annotation rate, 2.5 Hz), ``.csv`` or ``.jsonl``
    tracks (ticks at their median sample step). ``areas`` (for instance those kept in the
    store) are added to the file's own areas.
    ``holders`` ("none", "humans" or ids) overrides the file's ``belief_holders`` (config of a
    scenario); by default the humans of a scenario hold beliefs, those of a recording do not.
    ``config`` (producer thresholds, see :mod:`toaster.world.config`) is laid over the
    file's own config; it is validated here, before anything is stored. ROS bags (``.bag``,
    ``.mcap``, ``.db3``, a rosbag2 folder) are read whole first (:mod:`toaster.world.bags`,
    with ``tf_map`` and ``pose_topics`` as ``toaster serve --ros1``) and tick at the rate
    their entities are seen.
    """
    path = Path(path)
    config_over = config
    world = World()
    suffix = path.suffix.lower()
    if (tf_map is not None or pose_topics) and not is_bag(path):
        msg = f"--tf-map and --pose-topic are for ROS bags, not {path.name}"
        raise InvalidInputError(msg)
    if path.is_dir() and not is_bag(path):
        msg = (
            f"cannot run the folder {path.name!r}: give a file, or a rosbag2 folder (with "
            "metadata.yaml)"
        )
        raise FileFormatError(msg)
    if fps is not None and suffix != ".txt":
        msg = (
            f"--fps is for obsmat .txt recordings (frame numbers): {path.name} gives its own "
            "times; use --rate for ticks per second"
        )
        raise InvalidInputError(msg)
    if suffix in (".yaml", ".yml", ".json"):
        scenario = load_scenario(path)
        source: Any = ScenarioSource(scenario)
        all_areas = {**(areas or {}), **scenario.areas}
        config, rate, self_id = scenario.config, scenario.rate_hz, scenario.self_id
        start, end = scenario.start_ns, scenario.end_ns
        kinds = {str(e["id"]): str(e.get("kind", "object")).lower() for e in scenario.entities}
        default_holders = "humans"
    elif is_bag(path):
        source = read_bag(path, tf_map=tf_map, pose_topics=pose_topics)
        all_areas, config, self_id = {**source.areas, **(areas or {})}, {}, ""
        rate = source.sample_hz or 30.0
        start, end = source.start_ns, source.end_ns
        kinds, default_holders = source.kinds, "none"
    elif suffix == ".txt":
        source = read_obsmat(path) if fps is None else read_obsmat(path, fps=fps)
        all_areas, config, self_id = dict(areas or {}), {}, ""
        rate = source.sample_hz or 2.5
        start, end = source.start_ns, source.end_ns
        kinds, default_holders = source.kinds, "none"
    elif suffix in (".csv", ".jsonl", ".ndjson"):
        source = read_tracks(path)
        all_areas, config, self_id = dict(areas or {}), {}, ""
        rate = source.sample_hz or 10.0  # the tracks' own rate
        start, end = source.start_ns, source.end_ns
        kinds, default_holders = source.kinds, "none"
    else:
        msg = (
            f"cannot run {path.name!r}: give a scenario (.yaml, .yml, .json) or a recording "
            "(obsmat .txt, .csv, .jsonl)"
        )
        raise FileFormatError(msg)
    if config_over:
        config = overlay_config(config, config_over)
    make_config(config)  # a bad threshold fails here, before anything is stored
    choice = holders if holders is not None else config.get("belief_holders")
    belief_holders = _belief_holders(
        default_holders if choice is None else choice, kinds, path.name
    )
    entities = source.scenario.entities if isinstance(source, ScenarioSource) else []
    spatial = bool(config.get("spatial") or any(e.get("role") for e in entities))
    producers = builtin_producers(config, all_areas, spatial=spatial)
    return Session(
        world,
        [source],
        producers,
        all_areas,
        self_id or DEFAULT_SELF,
        start,
        end,
        rate,
        config,
        belief_holders,
        agent_views=isinstance(source, ScenarioSource),
    )
