"""The ROS 1 transport of a live node: subscribers feed named LiveSources, an output publishes
each tick's facts, TF frames and markers, and the original's services call the control plane.

Threads: rospy runs callbacks and services on its own threads. Callbacks only push poses into
thread-safe LiveSources and queue warning lines; services use their own database connections
(:class:`~toaster.ros1.services.DbPool`), once the node's writer stored the ticks before them.
Everything that reads the world runs on the node's thread (the output, and the queries the
node answers between ticks).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from toaster.db import catalog
from toaster.errors import InvalidInputError, one_line
from toaster.outputs import markers
from toaster.producers.registry import NAMES as PRODUCERS
from toaster.producers.seen import SeenFacts
from toaster.ros1 import messages, wire
from toaster.ros1.available import import_rospy
from toaster.ros1.dbcalls import AREA_KEY, AREA_SCOPE
from toaster.ros1.inputs import PoseInputs
from toaster.ros1.published import TABLES_TOPIC, AreaOut, TablesOut
from toaster.ros1.services import DbPool, Handlers
from toaster.ros1.tickout import PDG_LISTS, TickOutput
from toaster.ros1.watchers import Watchers
from toaster.world.drops import Drops
from toaster.world.live import LiveSource
from toaster.world.rosmsg import (
    FIXED_FRAME,
    FrameTarget,
    TfTree,
    frame_target,
    read_frame_map,
)
from toaster.world.state import World

#: the node's status line (std_msgs/String, latched) and the service that answers it now
STATUS_TOPIC, STATUS_SERVICE = "/toaster/status", "/toaster/get_status"
SIMU_LISTS = {
    "toaster_simu_human": ("/toaster_simu/humanList", "HumanListStamped"),
    "toaster_simu_robot": ("/toaster_simu/robotList", "RobotListStamped"),
    "toaster_simu_object": ("/toaster_simu/objectList", "ObjectListStamped"),
}


class Warnings:
    """Warning lines from rospy threads, each key at most once per ``every_s``; the node's
    thread drains them into ``node.warn``. At most ``MAX_KEYS`` keys are remembered (the
    oldest are forgotten), so keys naming values cannot make it grow."""

    MAX_KEYS = 1000

    def __init__(self, every_s: float = 10.0) -> None:
        self.every_s = every_s
        self._lines: list[str] = []
        self._last: dict[str, float] = {}
        self._lock = threading.Lock()

    def add(self, key: str, line: str) -> None:
        now = time.monotonic()
        with self._lock:
            if now - self._last.get(key, -1e18) >= self.every_s:
                self._last.pop(key, None)
                self._last[key] = now  # newest last: the first keys are the oldest
                if len(self._last) > self.MAX_KEYS:
                    for old in list(self._last)[: self.MAX_KEYS // 2]:
                        del self._last[old]
                self._lines.append(one_line(line))

    def drain(self) -> list[str]:
        with self._lock:
            out, self._lines = self._lines, []
        return out


def _one_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def pose_topic_targets(topics: Mapping[str, Any] | None) -> dict[str, FrameTarget]:
    """``{topic: "id" | "id:kind" | (id, kind) | {id, kind, owner?, joint?}}`` as targets."""
    out: dict[str, FrameTarget] = {}
    for topic, value in (topics or {}).items():
        if isinstance(value, str):
            entity_id, _, kind = value.partition(":")
            value = {"id": entity_id, "kind": kind or "object"}
        elif isinstance(value, tuple | list):
            value = {"id": value[0], "kind": value[1] if len(value) > 1 else "object"}
        out[topic] = frame_target(topic, value)
    return out


class Bridge(PoseInputs):
    """A running ROS 1 bridge; :meth:`shutdown` detaches it from the node."""

    def __init__(
        self,
        node: Any,
        rospy: Any,
        registry: messages.Registry,
        *,
        tf_map: Any = None,
        pose_topics: Mapping[str, Any] | None = None,
        publish_tf: bool = True,
        markers: bool = True,
        fixed_frame: str = FIXED_FRAME,
        toaster_simu: bool = True,
        pdg_lists: bool = False,
        publish_lists: bool = True,
        ros4hri: bool = True,
        services: bool = True,
    ) -> None:
        self.node, self.rospy, self.registry = node, rospy, registry
        self.warnings = Warnings()
        self.drops: Drops = node.drops
        self.tree = TfTree(fixed_frame)
        self.frames = read_frame_map(tf_map)
        self.topics = pose_topic_targets(pose_topics)
        self.publish_tf, self.markers = publish_tf, markers
        self.publish_lists = publish_lists and not pdg_lists  # never read back what we publish
        self.ros4hri = ros4hri
        self.tracked: dict[str, set[str] | None] = {"body": None, "face": None}
        # ROS4HRI's tracked lists are what the robot detects: IsSeen (producers/seen.py)
        self.seen = next((p for p in node.producers if p.name == SeenFacts.name), None)
        self.sources: dict[str, LiveSource] = {}
        self.subscribers: list[Any] = []
        self.services: list[Any] = []
        self._clock_pub: Any = None  # toaster run --ros1 (clock())
        self.pool: DbPool | None = None
        self.watchers: Watchers | None = None
        self._caller = rospy.get_name()
        self._area_numbers: tuple[frozenset[str], dict[str, int]] = (frozenset(), {})
        self._tf_lock = threading.Lock()
        self._tf_changed: set[str] = set()
        self._tf_readers: dict[tuple[str, str], wire.TfReader] = {}
        self._flush = _TfFlush(self)
        self._hri_key: tuple[int, int] = (-1, 0)
        self._tracked_version = 0  # moves with every tracked list received
        self._hri_cache: dict[str, FrameTarget] = {}
        self._subscribe(toaster_simu, pdg_lists)
        self._advertise()
        if services:
            self._serve()
        self.output = TickOutput(self)
        node.outputs.append(self.output)

    # -- inputs --------------------------------------------------------------------------------
    def _sub(self, topic: str, cls: Any, callback: Any, *args: Any) -> None:
        def guarded(msg: Any) -> None:
            try:
                callback(msg, *args)
            except Exception as exc:  # a callback never raises into rospy
                self.drops.drop(topic, "message", f"{type(exc).__name__}: {_one_line(exc)}")

        # tcp_nodelay: no Nagle wait on the sender's side for a pose (tens of ms otherwise)
        self.subscribers.append(
            self.rospy.Subscriber(topic, cls, guarded, queue_size=10, tcp_nodelay=True)
        )

    def _subscribe(self, toaster_simu: bool, pdg_lists: bool) -> None:
        from geometry_msgs.msg import PoseStamped  # type: ignore[import-not-found]

        reg = self.registry
        self.node.sources.append(self._flush)  # before the tf and ros4hri sources it feeds
        for name in ("tf", "pose_topics", "ros4hri"):
            self.source(name)
        # /tf as bytes: our own /tf is dropped unread, the others read as arrays (wire.py)
        self._sub("/tf", self.rospy.AnyMsg, self._on_tf, "/tf")
        self._sub("/tf_static", self.rospy.AnyMsg, self._on_tf, "/tf_static")
        for topic, target in self.topics.items():
            self._sub(topic, PoseStamped, self._on_pose, topic, target)
        if toaster_simu:
            for name, (topic, type_name) in SIMU_LISTS.items():
                self._sub(topic, reg.msg(type_name), self._on_list, name, topic)
        if pdg_lists:
            for topic, type_name, _ in PDG_LISTS.values():
                self._sub(topic, reg.msg(type_name), self._on_list, "pdg_lists", topic)
        if self.ros4hri:
            ids = reg.msg("hri_msgs/IdsList")
            self._sub("/humans/bodies/tracked", ids, self._on_tracked, "body")
            self._sub("/humans/faces/tracked", ids, self._on_tracked, "face")

    def _own(self, msg: Any) -> bool:
        header = getattr(msg, "_connection_header", None) or {}
        return header.get("callerid") == self._caller

    def _on_tf(self, msg: Any, topic: str) -> None:
        """Only store the transforms here (rospy's receive thread): the poses of the frames
        they moved are computed once per tick on the tick's thread (:class:`_TfFlush`), so the
        two threads do not fight over the interpreter for every message. The message comes as
        bytes (``rospy.AnyMsg``), read as arrays by a reader per publisher (each keeps its
        layout); the node's own /tf is dropped before it is read."""
        if self._own(msg):
            return
        header = getattr(msg, "_connection_header", None) or {}
        key = (topic, str(header.get("callerid", "")))
        reader = self._tf_readers.get(key)
        if reader is None:
            if len(self._tf_readers) >= 64:  # publishers come and go: forget the layouts
                self._tf_readers.clear()
            reader = self._tf_readers[key] = wire.TfReader()
        changed, bad = self.tree.update_edges(reader.read(msg._buff))
        for line in bad:
            self.drops.drop("/tf", "transform", line)
        with self._tf_lock:
            self._tf_changed |= changed
        wake = self.sources["tf"].on_push
        if wake is not None:
            wake()

    # -- outputs and services ------------------------------------------------------------------
    def _advertise(self) -> None:
        from std_msgs.msg import String  # type: ignore[import-not-found]
        from tf2_msgs.msg import TFMessage  # type: ignore[import-not-found]
        from visualization_msgs.msg import MarkerArray  # type: ignore[import-not-found]

        pub, reg = self.rospy.Publisher, self.registry
        # latched: a subscriber that comes later gets the last status line at once
        self.status_pub = pub(STATUS_TOPIC, String, queue_size=1, latch=True)
        trigger = reg.srv("std_srvs/Trigger")
        self.services.append(
            self.rospy.Service(
                STATUS_SERVICE, trigger, self._guard(STATUS_SERVICE, trigger, self._get_status)
            )
        )
        self.fact_pubs = {
            p: pub(f"/{p}/factList", reg.msg("FactList"), queue_size=10) for p in PRODUCERS
        }
        self.area_pub = pub("/area_manager/areaList", reg.msg("AreaList"), queue_size=10)
        self.areas_out = AreaOut(self.node, reg, self.area_pub, self.area_numbers)
        self.tables_pub = pub(TABLES_TOPIC, reg.msg("DatabaseTables"), queue_size=1)
        self.tables_out = TablesOut(self.node, reg, self.tables_pub)
        self.tf_pub = pub("/tf", TFMessage, queue_size=100) if self.publish_tf else None
        self.marker_pubs = (
            {t: pub(t, MarkerArray, queue_size=10) for t in markers.MARKER_TOPICS}
            if self.markers
            else {}
        )
        self.list_pubs = (
            {
                k: pub(topic, reg.msg(type_name), queue_size=10)
                for k, (topic, type_name, _) in PDG_LISTS.items()
            }
            if self.publish_lists
            else {}
        )

    def _get_status(self, req: Any, resp: Any) -> Any:
        resp.success, resp.message = True, self.node.status()
        return resp

    def _serve(self) -> None:
        db = self.node.db
        url = getattr(db, "url", "") if db is not None else ""
        if not url or ":memory:" in url:
            self.node.warn(
                "ROS services are off: they need a database file or server that "
                "a second connection can open (not :memory:)"
            )
            return
        self.pool = DbPool(url, before=getattr(self.node, "flush_writes", lambda: None))
        handlers = Handlers(
            self.pool,
            self.registry,
            lambda line: self.warnings.add(line, line),
            log=self.rospy.loginfo,
            area_lists=self.areas_out.ask,
        )
        watchers = self.watchers = Watchers(self.rospy, self.registry, url)

        def open_watch(req: Any, resp: Any) -> Any:
            resp.topic = watchers.open(req.agentId, req.subjectId, req.property, req.targetId)
            resp.answer = True
            return resp

        def publish_all_areas(req: Any, resp: Any) -> Any:
            on = self.areas_out.toggle()
            self.rospy.loginfo(f"/area_manager/areaList is {'on' if on else 'off'}")
            return resp

        table = [
            *handlers.table(),
            ("/database_manager/watch", "Watch", open_watch),
            ("/area_manager/publish_all_areas", "Empty", publish_all_areas),
        ]
        for name, type_name, handler in table:
            srv = self.registry.srv(type_name)
            self.services.append(self.rospy.Service(name, srv, self._guard(name, srv, handler)))

    def _guard(self, name: str, srv: Any, handler: Any) -> Any:
        def call(req: Any) -> Any:
            resp = srv._response_class()
            try:
                return handler(req, resp)
            except Exception as exc:  # a bad request fails this call only
                line = f"{name}: {_one_line(exc)}"
                self.drops.drop(name, getattr(exc, "field", "request"), _one_line(exc), "refused")
                for field in ("answer", "boolAnswer"):
                    if hasattr(resp, field):
                        setattr(resp, field, False)
                        return resp
                raise self.rospy.ServiceException(line) from None

        return call

    def area_numbers(self, names: frozenset[str]) -> dict[str, int]:
        """The original's numeric ids of the areas (re-read when the set of areas changes)."""
        if names != self._area_numbers[0] and self.node.db is not None:
            with self.node.read_db.transaction() as conn:  # the node's thread's connection
                stored = catalog.get_setting(conn, AREA_SCOPE, AREA_KEY, {}) or {}
            self._area_numbers = (names, {k: int(v) for k, v in stored.items()})
        return self._area_numbers[1]

    # -- a run's extras (toaster run --ros1) ----------------------------------------------------
    def listened(self) -> bool:
        """Whether a subscriber is connected to one of the outputs' topics."""
        pubs = [
            *self.fact_pubs.values(),
            *self.marker_pubs.values(),
            *self.list_pubs.values(),
            self.area_pub,
            self.tables_pub,
            self.tf_pub,
        ]
        return any(p is not None and p.get_num_connections() for p in pubs)

    def clock(self) -> Callable[[int], None]:
        """A /clock publisher (rosgraph_msgs/Clock) as ``tell(t_ns)``: what ``rosbag play
        --clock`` gives nodes with ``use_sim_time``."""
        from rosgraph_msgs.msg import Clock  # type: ignore[import-not-found]

        pub = self.rospy.Publisher("/clock", Clock, queue_size=1)
        self._clock_pub = pub

        def tell(t_ns: int) -> None:
            pub.publish(Clock(clock=self.rospy.Time(t_ns // 1_000_000_000, t_ns % 1_000_000_000)))

        return tell

    def shutdown(self) -> None:
        """Stop subscribers, services and publishers; detach from the node."""
        for sub in self.subscribers:
            sub.unregister()
        for srv in self.services:
            srv.shutdown("toaster bridge stopped")
        for pub in [
            *self.fact_pubs.values(),
            self.area_pub,
            self.tables_pub,
            self.tf_pub,
            self.status_pub,
            *self.marker_pubs.values(),
            *self.list_pubs.values(),
            self._clock_pub,
        ]:
            if pub is not None:
                pub.unregister()
        if self.output in self.node.outputs:
            self.node.outputs.remove(self.output)
        for source in [self._flush, *self.sources.values()]:
            if source in self.node.sources:
                self.node.sources.remove(source)
        if self.watchers is not None:
            self.watchers.close()
        if self.pool is not None:
            self.pool.close()
        self.rospy.signal_shutdown("toaster bridge stopped")


class _TfFlush:
    """A node source that turns the /tf received since the last tick into poses."""

    name = "tf_flush"

    def __init__(self, bridge: Bridge) -> None:
        self.bridge = bridge

    def setup(self, world: World) -> None:
        """Nothing to register."""

    def newest_stamp(self, wall_ns: int) -> int | None:
        """Push the /tf received so far before the node peeks at the stamps of the tf
        sources, which come after this one (toaster.node.stamps); none of its own."""
        self.bridge.flush_tf()
        return None

    def advance(self, world: World, t_ns: int) -> None:
        self.bridge.flush_tf()


def start_bridge(
    node: Any,
    *,
    node_name: str = "toaster",
    tf_map: str | Path | Mapping[str, Any] | None = None,
    pose_topics: Mapping[str, Any] | None = None,
    publish_tf: bool = True,
    markers: bool = True,
    **options: Any,
) -> Bridge:
    """Connect a :class:`~toaster.node.LiveNode` to ROS 1 (a roscore must be running).

    ``tf_map``: frame -> {id, kind, owner?, joint?} (a YAML/JSON file or a mapping) for
    ``/tf``; ``pose_topics``: PoseStamped topic -> "id[:kind]". Other options:
    ``fixed_frame`` ("map"), ``toaster_simu`` (read the toaster_simu lists, True),
    ``pdg_lists`` (read /pdg lists instead of publishing them, False), ``publish_lists``
    (True), ``ros4hri`` (True), ``services`` (True). rospy handles no signal: the live loop
    stops on SIGINT/SIGTERM and the caller calls :meth:`Bridge.shutdown`.
    """
    rospy = import_rospy()
    registry = messages.load()
    frames = read_frame_map(tf_map)  # bad maps fail before anything starts
    unknown = set(options) - {
        "fixed_frame",
        "toaster_simu",
        "pdg_lists",
        "publish_lists",
        "ros4hri",
        "services",
    }
    if unknown:
        msg = f"start_bridge: unknown option(s) {sorted(unknown)}"
        raise InvalidInputError(msg)
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    # rospy threads receive while the tick thread computes: hand the interpreter over every
    # 1 ms instead of 5 so that a pose does not wait behind a tick (docs/live.md, "Latency")
    sys.setswitchinterval(0.001)
    rospy.init_node(node_name, anonymous=False, disable_signals=True)
    for handler in handlers:  # rospy's logging set-up replaces them: keep the caller's too
        if handler not in root.handlers:
            handler.setLevel(max(handler.level, level))  # without rospy's INFO chatter
            root.addHandler(handler)
    return Bridge(
        node,
        rospy,
        registry,
        tf_map=frames,
        pose_topics=pose_topics,
        publish_tf=publish_tf,
        markers=markers,
        **options,
    )
