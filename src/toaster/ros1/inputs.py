"""What both ROS bridges do with the poses they receive, ROS 1 (rospy) or ROS 2 (DDS): the input
streams, /tf flushed at each tick, ROS4HRI tracked lists, PoseStamped topics and the
toaster_simu lists. Plain Python: no rospy, no cyclonedds."""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Any

from toaster.world.live import LiveSource
from toaster.world.rosmsg import (
    FrameTarget,
    PoseUpdate,
    TfTree,
    hri_target,
    list_updates,
    pose_stamped_update,
    tracked_ids,
)

if TYPE_CHECKING:
    from toaster.world.drops import Drops


class PoseInputs:
    """The input half of a bridge; the bridge's ``__init__`` sets the attributes below."""

    node: Any
    drops: Drops
    tree: TfTree
    frames: dict[str, FrameTarget]
    ros4hri: bool
    warnings: Any
    seen: Any
    sources: dict[str, LiveSource]
    tracked: dict[str, set[str] | None]
    _tf_lock: threading.Lock
    _tf_changed: set[str]
    _hri_key: tuple[int, int]
    _tracked_version: int
    _hri_cache: dict[str, FrameTarget]

    def source(self, name: str) -> LiveSource:
        """The LiveSource of an input stream (made and added to the node on first use); its
        refusals are counted in the node's ``drops``."""
        if name not in self.sources:
            self.sources[name] = LiveSource(name, drops=self.drops)
            self.node.sources.append(self.sources[name])
        return self.sources[name]

    def push(self, source: str, update: PoseUpdate, topic: str) -> None:
        """Queue a pose; a bad one is dropped and counted under ``topic`` (LiveSource.push
        runs the store's checks)."""
        self.source(source).push(
            update.entity_id,
            update.position,
            quat=update.quat,
            t_ns=update.t_ns,
            kind=update.kind,
            owner_id=update.owner_id,
            joint=update.joint,
            topic=topic,
        )

    def flush_tf(self) -> None:
        """Push the poses of the mapped (and ROS4HRI) frames moved since the last tick, as
        arrays (:meth:`TfTree.poses`, :meth:`LiveSource.push_many`)."""
        with self._tf_lock:
            changed, self._tf_changed = self._tf_changed, set()
        if not changed:
            return
        poses, lost = self.tree.poses(self.frames, changed)
        self.source("tf").push_many(poses.targets, poses.pos, poses.quat, poses.stamps, topic="/tf")
        if self.ros4hri:
            hri = self._hri_frames()
            if hri:
                found, _ = self.tree.poses(hri, changed)
                self.source("ros4hri").push_many(
                    found.targets, found.pos, found.quat, found.stamps, topic="/tf"
                )
        for frame in lost:
            self.warnings.add(
                f"lost:{frame}",
                f"/tf: frame {frame!r} "
                f"({self.frames[frame].entity_id}) does not reach "
                f"{self.tree.fixed!r}: its pose is not known",
            )

    def _hri_frames(self) -> dict[str, FrameTarget]:
        """The ROS4HRI frames of the tree (worked out again when frames or tracked lists
        change, not every tick)."""
        key = (self.tree.generation, self._tracked_version)
        if key != self._hri_key:
            frames = self.tree.frames()
            self._hri_cache = {f: t for f in frames if (t := self._hri(f)) is not None}
            self._hri_key = key
        return self._hri_cache

    def _hri(self, frame: str) -> FrameTarget | None:
        target = hri_target(frame)
        if target is None:
            return None
        which = "body" if frame.startswith("body_") else "face"
        tracked = self.tracked[which]
        human = target.owner_id or target.entity_id
        return target if tracked is None or human in tracked else None

    def _on_tracked(self, msg: Any, which: str) -> None:
        self.tracked[which] = ids = tracked_ids(msg)
        self._tracked_version += 1
        if self.seen is not None:
            self.seen.report(f"ros4hri_{which}", ids, self.node.self_id)

    def _on_pose(self, msg: Any, topic: str, target: FrameTarget) -> None:
        try:
            update = pose_stamped_update(msg, target.entity_id, target.kind, tree=self.tree)
        except ValueError as exc:
            self.drops.drop(topic, "pose", str(exc))
            return
        self.push(
            "pose_topics", update._replace(owner_id=target.owner_id, joint=target.joint), topic
        )

    def _on_list(self, msg: Any, source: str, topic: str) -> None:
        updates, bad = list_updates(msg)
        for line in bad:
            self.drops.drop(topic, "pose", line)
        for update in updates:
            self.push(source, update, topic)
