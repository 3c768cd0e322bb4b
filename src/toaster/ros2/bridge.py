"""The ROS 2 transport of a live node, over DDS without a ROS 2 install (cyclonedds): the ROS 1
bridge's inputs and outputs with ROS 2 names, types and QoS.

In: /tf and /tf_static (tf2_msgs/TFMessage; /tf_static transient local), PoseStamped topics,
ROS4HRI's hri_msgs/IdsList on /humans/bodies/tracked and /humans/faces/tracked, toaster_simu's
entity lists. Out (:mod:`toaster.ros2.output`): the fact lists, /tf, the markers, the area
list (transient local), the status line (transient local). Services: :mod:`toaster.ros2.services`.

Threads as in the ROS 1 bridge: cyclonedds' receive thread only pushes poses into LiveSources
and stores transforms; everything that reads the world runs on the node's thread.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from toaster.errors import InvalidInputError
from toaster.extras import require
from toaster.producers.seen import SeenFacts
from toaster.ros1.bridge import SIMU_LISTS, STATUS_SERVICE, STATUS_TOPIC, Warnings
from toaster.ros1.bridge import pose_topic_targets as pose_targets
from toaster.ros1.inputs import PoseInputs
from toaster.ros2 import cdr, names
from toaster.ros2.dds import TF_DEPTH, Dds
from toaster.ros2.idl import Types
from toaster.world.drops import Drops
from toaster.world.live import LiveSource
from toaster.world.rosmsg import (
    FIXED_FRAME,
    FrameTarget,
    TfTree,
    read_frame_map,
)

__all__ = ["STATUS_SERVICE", "STATUS_TOPIC", "Ros2Bridge", "start_bridge"]
CLOCK, CLOCK_TOPIC = "rosgraph_msgs/msg/Clock", "/clock"
OPTIONS = ("fixed_frame", "toaster_simu", "ros4hri", "services", "publish_tf", "markers")


def _one_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


class Ros2Bridge(PoseInputs):
    """A running ROS 2 bridge; :meth:`shutdown` detaches it from the node."""

    def __init__(
        self,
        node: Any,
        domain: int,
        *,
        tf_map: Any = None,
        pose_topics: Mapping[str, Any] | None = None,
        fixed_frame: str = FIXED_FRAME,
        toaster_simu: bool = True,
        ros4hri: bool = True,
        services: bool = True,
        publish_tf: bool = True,
        markers: bool = True,
    ) -> None:
        from toaster.ros1.bridge import _TfFlush
        from toaster.ros2.output import Ros2Output
        from toaster.ros2.services import Server

        self.node = node
        self.types = Types()
        self.dds = Dds(domain, self.types)
        self.warnings = Warnings()
        self.drops: Drops = node.drops
        self.tree = TfTree(fixed_frame)
        self.frames = read_frame_map(tf_map)
        self.topics = pose_targets(pose_topics)
        self.ros4hri = ros4hri
        self.tracked: dict[str, set[str] | None] = {"body": None, "face": None}
        self.seen = next((p for p in node.producers if p.name == SeenFacts.name), None)
        self.sources: dict[str, LiveSource] = {}
        self._tf_lock = threading.Lock()
        self._tf_changed: set[str] = set()
        self._tracked_version = 0
        self._hri_key: tuple[int, int] = (-1, 0)
        self._hri_cache: dict[str, FrameTarget] = {}
        self._tf_readers = {"/tf": cdr.TfReader(), "/tf_static": cdr.TfReader()}
        self._flush = _TfFlush(self)  # type: ignore[arg-type]  # duck-typed: flush_tf
        self._subscribe(toaster_simu)
        self.output = Ros2Output(self, publish_tf=publish_tf, draw=markers)
        node.outputs.append(self.output)
        self.server = Server(self) if services else None

    # -- inputs --------------------------------------------------------------------------------
    def _sub(self, topic: str, msgtype: str, callback: Any, *args: Any, **kw: Any) -> None:
        def guarded(msg: Any) -> None:
            try:
                callback(msg, *args)
            except Exception as exc:  # a callback never raises into cyclonedds
                self.drops.drop(topic, "message", f"{type(exc).__name__}: {_one_line(exc)}")

        self.dds.reader(topic, msgtype, guarded, **kw)

    def _subscribe(self, toaster_simu: bool) -> None:
        self.node.sources.append(self._flush)  # before the tf and ros4hri sources it feeds
        for name in ("tf", "pose_topics", "ros4hri"):
            self.source(name)
        tf = "tf2_msgs/msg/TFMessage"
        # /tf as bytes, read as arrays (cdr.py); the node's own /tf is not delivered back
        self._sub("/tf", tf, self._on_tf, "/tf", depth=TF_DEPTH, ignore_own=True, raw=True)
        self._sub(
            "/tf_static", tf, self._on_tf, "/tf_static", kind="latched", depth=TF_DEPTH, raw=True
        )
        for topic, target in self.topics.items():
            self._sub(topic, "geometry_msgs/msg/PoseStamped", self._on_pose, topic, target)
        if toaster_simu:
            for name, (topic, type_name) in SIMU_LISTS.items():
                msgtype = f"toaster_msgs/msg/{type_name}"
                self._sub(topic, msgtype, self._on_list, name, topic, kind="reliable")
        if self.ros4hri:
            for which in ("body", "face"):
                topic = f"/humans/{which}s/tracked"
                self._sub(topic, "hri_msgs/msg/IdsList", self._on_tracked, which)

    def _on_tf(self, data: bytes, topic: str) -> None:
        """Store the transforms (cyclonedds' receive thread); their frames' poses are worked
        out once per tick on the node's thread (:meth:`flush_tf`)."""
        changed, bad = self.tree.update_edges(self._tf_readers[topic].read(data))
        for line in bad:
            self.drops.drop(topic, "transform", line)
        with self._tf_lock:
            self._tf_changed |= changed
        wake = self.sources["tf"].on_push
        if wake is not None:
            wake()

    # -- a run's extras -------------------------------------------------------------------------
    def listened(self) -> bool:
        """Whether a reader matched one of the outputs' topics (``toaster run --wait``)."""
        out = self.output
        writers = [*out.fact_pubs.values(), *out.marker_pubs.values(), out.area_pub, out.tf_pub]
        return any(w is not None and self.dds.listened(w) for w in writers)

    def clock(self) -> Callable[[int], None]:
        """A /clock writer (rosgraph_msgs/msg/Clock, reliable, depth 1: every reader QoS,
        rclcpp's best-effort ClockQoS too) as ``tell(t_ns)``: what ``ros2 bag play --clock``
        gives nodes with ``use_sim_time``."""
        writer = self.dds.writer(CLOCK_TOPIC, CLOCK, "reliable", 1)

        def tell(t_ns: int) -> None:
            writer.write(self.types.build(CLOCK, {"clock": t_ns}))

        return tell

    # -- stopping ------------------------------------------------------------------------------
    def shutdown(self) -> None:
        """Stop the services, detach from the node, delete the DDS participant."""
        if self.server is not None:
            self.server.close()
        if self.output in self.node.outputs:
            self.node.outputs.remove(self.output)
        for source in [self._flush, *self.sources.values()]:
            if source in self.node.sources:
                self.node.sources.remove(source)
        self.dds.close()


def start_bridge(
    node: Any,
    *,
    domain_id: int | str | None = None,
    tf_map: str | Path | Mapping[str, Any] | None = None,
    pose_topics: Mapping[str, Any] | None = None,
    **options: Any,
) -> Ros2Bridge:
    """Connect a :class:`~toaster.node.LiveNode` to ROS 2 over DDS on ``domain_id``
    (default ``ROS_DOMAIN_ID``, else 0). Options: ``fixed_frame`` ("map"), ``toaster_simu``,
    ``ros4hri``, ``services``, ``publish_tf``, ``markers`` (all True)."""
    require("ros2", "toaster serve --ros2")
    domain = names.domain_id(domain_id)
    frames = read_frame_map(tf_map)  # bad maps fail before anything starts
    unknown = set(options) - set(OPTIONS)
    if unknown:
        msg = f"start_bridge: unknown option(s) {sorted(unknown)}; give {', '.join(OPTIONS)}"
        raise InvalidInputError(msg)
    # as the ROS 1 bridge: DDS's receive thread gets the interpreter within 1 ms of asking,
    # not 5, so that a pose does not wait behind a tick (docs/live.md, "Latency")
    sys.setswitchinterval(0.001)
    return Ros2Bridge(node, domain, tf_map=frames, pose_topics=pose_topics, **options)
