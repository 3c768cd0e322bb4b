"""TfTree keeps its transforms as arrays and composes the mapped frames of a crowd level by
level; the dictionary of edges and loop per frame it replaced are kept here as the reference:
on random trees (chains, cycles, frames that do not reach map, static stamps, a child moved
to another parent, a child twice in a message, bad transforms) both give the same changed
frames, lines, poses, lost frames and lookups, to the bit."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable, Mapping
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from toaster.model import check_id, shown
from toaster.world.geometry import IDENTITY, Quat, Vec, compose_poses
from toaster.world.rosmsg import (
    FIXED_FRAME,
    FrameTarget,
    PoseUpdate,
    TfTree,
    frame_target,
    quat,
    stamp_ns,
    strip_frame,
    tf_updates,
    vec,
)


class ReferenceTree:
    """The dictionary of edges and loop per frame that TfTree replaced (main @ 1b212f2)."""

    MAX_DEPTH = 64
    #: frames kept at most: a publisher inventing new frame names cannot make it grow further
    MAX_FRAMES = 10_000

    def __init__(self, fixed_frame: str = FIXED_FRAME) -> None:
        self.fixed = strip_frame(fixed_frame)
        self._edges: dict[str, tuple[str, Vec, Quat, int]] = {}
        self._lock = threading.Lock()

    def update(self, msg: Any) -> tuple[set[str], list[str]]:
        """Store the transforms of a TFMessage; return (children set, one line per bad one)."""
        changed: set[str] = set()
        bad: list[str] = []
        with self._lock:
            for tr in msg.transforms:
                child = strip_frame(tr.child_frame_id)
                parent = strip_frame(tr.header.frame_id)
                try:
                    check_id(child, "child frame")
                    check_id(parent, "parent frame")
                    t, q = vec(tr.transform.translation), quat(tr.transform.rotation)
                except ValueError as exc:  # InvalidInputError is one
                    bad.append(f"transform {shown(parent)} -> {shown(child)} ignored: {exc}")
                    continue
                if child == parent:
                    bad.append(
                        f"transform {shown(parent)} -> {shown(child)} ignored: not a tree edge"
                    )
                    continue
                if child not in self._edges and len(self._edges) >= self.MAX_FRAMES:
                    bad.append(
                        f"transform {shown(parent)} -> {shown(child)} ignored: "
                        f"{self.MAX_FRAMES} frames are known already"
                    )
                    continue
                self._edges[child] = (parent, t, q, stamp_ns(tr.header.stamp))
                changed.add(child)
        return changed, bad

    def chain(self, frame: str) -> list[str]:
        """Frames from ``frame`` up to its root (``frame`` first)."""
        out, current = [frame], frame
        with self._lock:
            while current in self._edges and len(out) <= self.MAX_DEPTH:
                current = self._edges[current][0]
                out.append(current)
        return out

    def lookup(self, frame: str) -> tuple[Vec, Quat, int | None] | None:
        """Pose of ``frame`` in the fixed frame and its newest stamp (None when all stamps
        are 0, as static transforms); None when no chain of transforms reaches the fixed
        frame."""
        return self.lookup_many([frame])[0]

    def lookup_many(self, frames: list[str]) -> list[tuple[Vec, Quat, int | None] | None]:
        """:meth:`lookup` of many frames, composed together (one rotation batch per level)."""
        chains: list[list[tuple[str, Vec, Quat, int]] | None] = []
        with self._lock:
            for frame in frames:
                current = strip_frame(frame)
                edges: list[tuple[str, Vec, Quat, int]] = []
                while current != self.fixed and len(edges) < self.MAX_DEPTH:
                    edge = self._edges.get(current)
                    if edge is None:
                        break
                    edges.append(edge)
                    current = edge[0]
                chains.append(edges if current == self.fixed else None)
        found = [c for c in chains if c is not None]
        depth = max((len(c) for c in found), default=0)
        # level k holds each chain's k-th transform from the frame up, identity past its end
        lt = np.zeros((depth, len(found), 3))
        lq = np.tile(np.asarray(IDENTITY), (depth, len(found), 1))
        for i, chain in enumerate(found):
            for k, (_, et, eq, _) in enumerate(chain):
                lt[k, i], lq[k, i] = et, eq
        t, q = np.zeros((len(found), 3)), np.tile(np.asarray(IDENTITY), (len(found), 1))
        for k in range(depth):
            t, q = compose_poses(lt[k], lq[k], t, q)
        out: list[tuple[Vec, Quat, int | None] | None] = []
        i = 0
        for edges_up in chains:
            if edges_up is None:
                out.append(None)
                continue
            x, y, z = t[i].tolist()
            qx, qy, qz, qw = q[i].tolist()
            newest = max((e[3] for e in edges_up), default=0)
            out.append(((x, y, z), (qx, qy, qz, qw), newest or None))
            i += 1
        return out

    def frames(self) -> list[str]:
        """Every child frame known."""
        with self._lock:
            return list(self._edges)

    def frozen(self) -> ReferenceTree:
        """A copy that later messages do not change: poses composed from it all come from
        the same messages."""
        copy = ReferenceTree()
        copy.fixed = self.fixed
        with self._lock:
            copy._edges = dict(self._edges)
        return copy


def reference_updates(
    tree: ReferenceTree, targets: Mapping[str, FrameTarget], changed: Iterable[str]
) -> tuple[list[PoseUpdate], list[str]]:
    """Poses of the mapped frames whose chain contains a changed frame, and the mapped frames
    that do not reach the fixed frame, all composed from the tree as it was when called (a
    message arriving meanwhile on rospy's thread is not half seen: one human's body from it
    and its head from the one before, for one tick)."""
    tree = tree.frozen()
    changed = set(changed)
    updates: list[PoseUpdate] = []
    lost: list[str] = []
    wanted = [frame for frame in targets if changed.intersection(tree.chain(frame))]
    for frame, found in zip(wanted, tree.lookup_many(wanted), strict=True):
        target = targets[frame]
        if found is None:
            lost.append(frame)
            continue
        position, q, t_ns = found
        updates.append(
            PoseUpdate(
                target.entity_id, target.kind, position, q, t_ns, target.owner_id, target.joint
            )
        )
    return updates, lost


FRAMES = ["map", "odom", "/odom", "base", "b1", "b2", "b3", "b4", "h0", "h1", "h2", "cam", ""]


def _transform(rng: np.random.Generator, parent: str, child: str) -> SimpleNamespace:
    t = rng.normal(0, 2, 3).round(3).tolist()
    q = rng.normal(0, 1, 4).tolist()
    if rng.random() < 0.1:
        q = [0.0, 0.0, 0.0, 0.0]  # a message default: identity
    if rng.random() < 0.04:
        t[1] = math.inf
    if rng.random() < 0.03:
        q = [0.0, 0.0, 0.0, math.nan]
    stamp = 0 if rng.random() < 0.2 else int(rng.integers(1, 10**12))
    return SimpleNamespace(
        header=SimpleNamespace(
            frame_id=parent, stamp=SimpleNamespace(secs=stamp // 10**9, nsecs=stamp % 10**9)
        ),
        child_frame_id=child,
        transform=SimpleNamespace(
            translation=SimpleNamespace(x=t[0], y=t[1], z=t[2]),
            rotation=SimpleNamespace(x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )


def _message(rng: np.random.Generator) -> SimpleNamespace:
    out = []
    for _ in range(int(rng.integers(1, 9))):
        child = FRAMES[rng.integers(1, len(FRAMES))]
        parent = FRAMES[rng.integers(0, len(FRAMES))] if rng.random() < 0.4 else "map"
        out.append(_transform(rng, parent, child))
    return SimpleNamespace(transforms=out)


TARGETS = {
    f: frame_target(f, {"id": f"e_{f or 'x'}", "kind": "object"})
    for f in ["base", "b1", "b3", "b4", "h0", "h1", "cam", "odom", "nowhere", "map"]
}


@pytest.mark.parametrize("seed", range(60))
def test_arrays_compose_what_the_loop_per_frame_composed(seed):
    rng = np.random.default_rng(seed)
    new, ref = TfTree(), ReferenceTree()
    for _ in range(12):
        msg = _message(rng)
        got, want = new.update(msg), ref.update(msg)
        assert got == want
        changed = set(got[0]) | ({"b1"} if rng.random() < 0.3 else set())
        assert tf_updates(new, TARGETS, changed) == reference_updates(ref, TARGETS, changed)
        asked = [FRAMES[i] for i in rng.integers(0, len(FRAMES), 5)] + ["/b1", "nowhere"]
        assert new.lookup_many(asked) == ref.lookup_many(asked)
        for frame in asked:
            assert new.chain(frame) == ref.chain(frame)
        assert sorted(new.frames()) == sorted(ref.frames())


def test_a_crowd_message_gives_the_same_poses():
    rng = np.random.default_rng(1)
    new, ref = TfTree(), ReferenceTree()
    transforms = [_transform(rng, "map", f"h{i}_base") for i in range(300)]
    transforms += [_transform(rng, f"h{i}_base", f"h{i}_head") for i in range(300)]
    msg = SimpleNamespace(transforms=transforms)
    targets = {tr.child_frame_id: frame_target(tr.child_frame_id, "x") for tr in transforms}
    changed = new.update(msg)[0]
    assert changed == ref.update(msg)[0]
    assert tf_updates(new, targets, changed) == reference_updates(ref, targets, changed)


def test_frames_past_the_limit_are_refused_and_names_do_not_pile_up():
    tree = TfTree()
    tree.MAX_FRAMES = 5
    rng = np.random.default_rng(2)
    msg = SimpleNamespace(transforms=[_transform(rng, "map", f"f{i}") for i in range(7)])
    changed, bad = tree.update(msg)
    assert len(changed) == 5 and len(bad) == 2 and "5 frames are known" in bad[0]
    for k in range(2000):  # a publisher renaming the parent of one frame every message
        tree.update(SimpleNamespace(transforms=[_transform(rng, f"p{k}", "f0")]))
    assert len(tree._names) < 100
    assert tree.chain("f0") == ["f0", "p1999"]
