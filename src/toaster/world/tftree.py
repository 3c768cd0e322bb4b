"""The newest transform per TF child frame, kept as arrays, and the poses of mapped frames
composed up to the fixed frame for many frames at once (no rospy import).

Frame names are interned to integers; each has at most one edge (its newest transform to its
parent). A message is stored with one dictionary lookup per transform and array assignments;
poses are composed level by level over all the frames asked at once (:meth:`TfTree.poses`), so
a crowd's /tf costs a few array operations a tick instead of a loop per frame.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from toaster.model import check_id, shown
from toaster.world.geometry import IDENTITY, Quat, Vec, check_quat, compose_poses

FIXED_FRAME = "map"


def strip_frame(frame: str) -> str:
    """A frame id without its leading slash (tf2 drops it too)."""
    return frame.lstrip("/")


def stamp_ns(stamp: Any) -> int:
    """ns since the epoch of a ROS 1 (secs/nsecs) or ROS 2 (sec/nanosec) stamp, or an int."""
    if stamp is None:
        return 0
    if isinstance(stamp, int):
        return stamp
    if hasattr(stamp, "secs"):
        return int(stamp.secs) * 1_000_000_000 + int(stamp.nsecs)
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def vec_of(x: object, y: object, z: object) -> Vec:
    """(x, y, z) as floats; ValueError when not finite."""
    out = (float(x), float(y), float(z))  # type: ignore[arg-type]
    if not all(np.isfinite(c) for c in out):
        msg = f"position {list(out)} must be finite numbers (metres)"
        raise ValueError(msg)
    return out


def quat_of(x: object, y: object, z: object, w: object) -> Quat:
    """(x, y, z, w) normalised; an all-zero quaternion (a message default) is identity."""
    out = (float(x), float(y), float(z), float(w))  # type: ignore[arg-type]
    if out == (0.0, 0.0, 0.0, 0.0):
        return IDENTITY
    return check_quat(out)


class Edges(NamedTuple):
    """Transforms as arrays: child and parent frame names, stamps (ns), translations (n, 3)
    and rotations (n, 4) (x, y, z, w), as a message lists them."""

    children: Sequence[str]
    parents: Sequence[str]
    stamps: np.ndarray
    t: np.ndarray
    q: np.ndarray


class Poses(NamedTuple):
    """Composed poses of mapped frames: their targets, positions (n, 3), quaternions (n, 4),
    and newest stamps (None when all are 0, as static transforms)."""

    targets: list[Any]
    pos: np.ndarray
    quat: np.ndarray
    stamps: list[int | None]


def edges_of(msg: Any) -> Edges:
    """The transforms of a TFMessage (ROS 1 or 2 classes, or anything shaped like them)."""
    ts = list(msg.transforms)
    return Edges(
        [tr.child_frame_id for tr in ts],
        [tr.header.frame_id for tr in ts],
        np.array([stamp_ns(tr.header.stamp) for tr in ts], dtype=object),
        np.array(
            [
                (tr.transform.translation.x, tr.transform.translation.y, tr.transform.translation.z)
                for tr in ts
            ],
            dtype=object,
        ).reshape(-1, 3),
        np.array(
            [
                (
                    tr.transform.rotation.x,
                    tr.transform.rotation.y,
                    tr.transform.rotation.z,
                    tr.transform.rotation.w,
                )
                for tr in ts
            ],
            dtype=object,
        ).reshape(-1, 4),
    )


class TfTree:
    """The newest transform per child frame; poses composed up to the fixed frame.

    Thread-safe (``/tf`` and ``/tf_static`` arrive on different threads; the tick composes).
    """

    MAX_DEPTH = 64
    #: frames kept at most: a publisher inventing new frame names cannot make it grow further
    MAX_FRAMES = 10_000

    def __init__(self, fixed_frame: str = FIXED_FRAME) -> None:
        self.fixed = strip_frame(fixed_frame)
        self._lock = threading.Lock()
        self._names_ok: dict[str, str] = {}  # raw frame id -> checked, stripped name
        self._reset([])

    def _reset(self, keep: list[tuple[str, str, Vec | np.ndarray, Any, int]]) -> None:
        """Intern anew, keeping the edges ``keep`` (child, parent, t, q, stamp) (lock held)."""
        self._last: tuple[list, list, np.ndarray, np.ndarray, frozenset[str]] | None = None
        self._plans: dict[int, tuple[int, np.ndarray, list[str]]] = {}
        self._index: dict[str, int] = {}
        self._names: list[str] = []
        cap = max(16, 2 * len(keep))
        self._parent = np.full(cap, -1, np.int64)
        self._has = np.zeros(cap, bool)
        self._t = np.zeros((cap, 3))
        self._q = np.tile(np.asarray(IDENTITY), (cap, 1))
        self._stamp = np.zeros(cap, np.int64)
        self._children: list[str] = []  # in the order they were first stored
        self._intern(self.fixed)
        for child, parent, t, q, stamp in keep:
            c = self._intern(child)
            self._link(c, parent)
            self._t[c], self._q[c], self._stamp[c] = t, q, stamp
        self._names_ok = {k: v for k, v in self._names_ok.items() if v in self._index}

    def _intern(self, name: str) -> int:
        got = self._index.get(name)
        if got is None:
            got = self._index[name] = len(self._names)
            self._names.append(name)
            if got >= len(self._parent):
                grow = len(self._parent)
                self._parent = np.concatenate([self._parent, np.full(grow, -1, np.int64)])
                self._has = np.concatenate([self._has, np.zeros(grow, bool)])
                self._t = np.concatenate([self._t, np.zeros((grow, 3))])
                self._q = np.concatenate([self._q, np.tile(np.asarray(IDENTITY), (grow, 1))])
                self._stamp = np.concatenate([self._stamp, np.zeros(grow, np.int64)])
        return got

    def _link(self, child: int, parent: str) -> None:
        if not self._has[child]:
            self._has[child] = True
            self._children.append(self._names[child])
        self._parent[child] = self._intern(parent)

    def _name(self, raw: object, what: str) -> str:
        """A frame id checked and stripped (cached); ValueError as :func:`check_id`."""
        got = self._names_ok.get(raw) if isinstance(raw, str) else None
        if got is None:
            got = strip_frame(raw)  # type: ignore[arg-type]
            check_id(got, what)
            if len(self._names_ok) < 4 * self.MAX_FRAMES:
                self._names_ok[raw] = got  # type: ignore[index]
        return got

    # -- storing ----------------------------------------------------------------------------------
    def update(self, msg: Any) -> tuple[set[str], list[str]]:
        """Store the transforms of a TFMessage; return (children set, one line per bad one)."""
        return self.update_edges(edges_of(msg))

    def update_edges(self, edges: Edges) -> tuple[set[str], list[str]]:
        """Store transforms (in order: a later one of a child wins); return (children set,
        one line per bad one)."""
        n = len(edges.children)
        t, q, stamps = _numbers(edges.t, 3, n), _numbers(edges.q, 4, n), edges.stamps
        t_ok = np.isfinite(t).all(axis=1)
        zero = (q == 0.0).all(axis=1)
        qx, qy, qz, qw = q.T
        norm = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)  # check_quat's, in its order
        q_ok = zero | (np.isfinite(norm) & (norm != 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = np.where(zero[:, None], np.asarray(IDENTITY), q / norm[:, None])
        changed: set[str] = set()
        bad: list[str] = []
        rows: list[int] = []
        slots: list[int] = []
        with self._lock:
            last = self._last
            if (
                last is not None
                and last[0] == edges.children
                and last[1] == edges.parents
                and bool(t_ok.all() and q_ok.all())
            ):  # a stream: the frames of the previous message, in its order
                r, s, names = last[2], last[3], last[4]
                self._t[s], self._q[s], self._stamp[s] = t[r], unit[r], _ints(stamps, r)
                return set(names), []
            for i in range(n):
                raw_child, raw_parent = edges.children[i], edges.parents[i]
                try:
                    child = self._name(raw_child, "child frame")
                    parent = self._name(raw_parent, "parent frame")
                    if not (t_ok[i] and q_ok[i]):
                        vec_of(*edges.t[i])
                        quat_of(*edges.q[i])
                except ValueError as exc:  # InvalidInputError is one
                    child, parent = strip_frame(raw_child), strip_frame(raw_parent)
                    bad.append(f"transform {shown(parent)} -> {shown(child)} ignored: {exc}")
                    continue
                if child == parent:
                    bad.append(
                        f"transform {shown(parent)} -> {shown(child)} ignored: not a tree edge"
                    )
                    continue
                c = self._index.get(child)
                if (c is None or not self._has[c]) and len(self._children) >= self.MAX_FRAMES:
                    bad.append(
                        f"transform {shown(parent)} -> {shown(child)} ignored: "
                        f"{self.MAX_FRAMES} frames are known already"
                    )
                    continue
                if c is None:
                    c = self._intern(child)
                p = self._parent[c]
                if not self._has[c] or p < 0 or self._names[p] != parent:
                    self._link(c, parent)
                rows.append(i)
                slots.append(c)
                changed.add(child)
            r, s = np.asarray(rows, np.int64), np.asarray(slots, np.int64)
            if len(set(slots)) < len(slots):  # a child twice: its last transform wins
                _, at = np.unique(s[::-1], return_index=True)
                keep = np.sort(len(s) - 1 - at)
                r, s = r[keep], s[keep]
            if rows:
                self._t[s], self._q[s], self._stamp[s] = t[r], unit[r], _ints(stamps, r)
            self._last = None
            if not bad:
                self._last = (list(edges.children), list(edges.parents), r, s, frozenset(changed))
            if len(self._names) > 4 * len(self._children) + 64:
                self._reset(self._edges())
        return changed, bad

    def _edges(self) -> list[tuple[str, str, Any, Any, int]]:
        out = []
        for child in self._children:
            c = self._index[child]
            out.append(
                (child, self._names[self._parent[c]], self._t[c], self._q[c], int(self._stamp[c]))
            )
        return out

    # -- reading ----------------------------------------------------------------------------------
    def chain(self, frame: str) -> list[str]:
        """Frames from ``frame`` up to its root (``frame`` first)."""
        out, current = [frame], frame
        with self._lock:
            c = self._index.get(frame)
            while c is not None and self._has[c] and len(out) <= self.MAX_DEPTH:
                c = int(self._parent[c])
                current = self._names[c]
                out.append(current)
        return out

    def lookup(self, frame: str) -> tuple[Vec, Quat, int | None] | None:
        """Pose of ``frame`` in the fixed frame and its newest stamp (None when all stamps
        are 0, as static transforms); None when no chain of transforms reaches the fixed
        frame."""
        return self.lookup_many([frame])[0]

    def lookup_many(self, frames: list[str]) -> list[tuple[Vec, Quat, int | None] | None]:
        """:meth:`lookup` of many frames, composed together (one rotation batch per level)."""
        poses, found, _ = self._compose([strip_frame(f) for f in frames], None, None)
        out: list[tuple[Vec, Quat, int | None] | None] = [None] * len(frames)
        for k, i in enumerate(found.tolist()):
            x, y, z = poses.pos[k].tolist()
            qx, qy, qz, qw = poses.quat[k].tolist()
            out[i] = ((x, y, z), (qx, qy, qz, qw), poses.stamps[k])
        return out

    def poses(
        self, targets: Mapping[str, Any], changed: Iterable[str] | None = None
    ) -> tuple[Poses, list[str]]:
        """Poses of the mapped frames (``targets``: frame -> what it is) whose chain holds a
        frame of ``changed`` (None: all), in the map's order, and the frames among them that
        do not reach the fixed frame; all composed from the tree as it is when called (a
        message arriving meanwhile is not half seen)."""
        frames = list(targets)
        poses, _, lost = self._compose(frames, changed, targets)
        return poses, lost

    def _compose(
        self, frames: list[str], changed: Iterable[str] | None, labels: Mapping[str, Any] | None
    ) -> tuple[Poses, np.ndarray, list[str]]:
        """Poses of ``frames`` (those whose chain holds a changed frame, when given) that reach
        the fixed frame, labelled by ``labels`` (None: the frames themselves); the positions in
        ``frames`` of those found; the frames wanted that do not reach it."""
        with self._lock:
            index, fixed = self._index, self._index[self.fixed]
            idx = self._plan(frames)
            parent, has = self._parent.copy(), self._has.copy()
            t_all, q_all, stamp_all = self._t.copy(), self._q.copy(), self._stamp.copy()
            if changed is not None:
                changed = set(changed)
                hit = np.zeros(len(self._names), bool)
                hit[[index[c] for c in changed if c in index]] = True
        known = idx >= 0
        if changed is not None:  # the chain: the frame and its parents (up to MAX_DEPTH)
            cur = np.where(known, idx, 0)
            wanted = known & hit[cur]
            for i in np.flatnonzero(~known).tolist():  # unknown frames: their chain is them
                wanted[i] = frames[i] in changed
            for _ in range(self.MAX_DEPTH):
                step = known & has[cur]
                if not step.any():
                    break
                cur = np.where(step, parent[cur], cur)
                wanted |= step & hit[cur]
            pick = np.flatnonzero(wanted)
        else:
            pick = np.arange(len(frames))
        start = idx[pick]
        # walk up to the fixed frame: level k holds each chain's k-th edge (-1 past its end)
        cur = start.copy()
        alive = start >= 0
        levels: list[np.ndarray] = []
        for _ in range(self.MAX_DEPTH):
            alive &= cur != fixed
            alive &= has[np.maximum(cur, 0)]
            if not alive.any():
                break
            levels.append(np.where(alive, cur, -1))
            cur = np.where(alive, parent[np.maximum(cur, 0)], cur)
        reach = cur == fixed
        lost = [frames[i] for i in pick[~reach].tolist()]
        found = np.flatnonzero(reach)
        rows = [lv[found] for lv in levels]
        depth = max((int((r >= 0).any()) and k + 1 for k, r in enumerate(rows)), default=0)
        m = len(found)
        t, q = np.zeros((m, 3)), np.tile(np.asarray(IDENTITY), (m, 1))
        low = np.iinfo(np.int64).min
        newest = np.full(m, low, np.int64)
        for k in range(depth):
            e = rows[k]
            used = e >= 0
            lt = np.where(used[:, None], t_all[np.maximum(e, 0)], 0.0)
            lq = np.where(used[:, None], q_all[np.maximum(e, 0)], np.asarray(IDENTITY))
            newest = np.maximum(newest, np.where(used, stamp_all[np.maximum(e, 0)], low))
            t, q = compose_poses(lt, lq, t, q)
        newest[newest == low] = 0  # no edge (the fixed frame itself)
        stamps: list[int | None] = [s or None for s in newest.tolist()]
        chosen = pick[found]
        named = [frames[i] for i in chosen.tolist()]
        if labels is not None:
            named = [labels[f] for f in named]
        return Poses(named, t, q, stamps), chosen, lost

    def _plan(self, frames: list[str]) -> np.ndarray:
        """The name index of each frame (-1: unknown), kept while no name is added (a frame
        map asked every tick; lock held)."""
        plan = self._plans.get(len(frames))
        if plan is None or plan[0] != len(self._names) or plan[2] != frames:
            idx = np.fromiter((self._index.get(f, -1) for f in frames), np.int64, len(frames))
            if len(self._plans) > 8:
                self._plans.clear()
            plan = self._plans[len(frames)] = (len(self._names), idx, list(frames))
        return plan[1]

    def frames(self) -> list[str]:
        """Every child frame known."""
        with self._lock:
            return list(self._children)

    @property
    def generation(self) -> int:
        """Grows when a new child frame is stored (callers cache what depends on the set)."""
        return len(self._children)


def _numbers(values: Any, width: int, n: int) -> np.ndarray:
    """Float (n, width) array of message numbers; NaN where one is not a number."""
    try:
        return np.asarray(values, dtype=float).reshape(n, width)
    except (TypeError, ValueError):
        out = np.full((n, width), np.nan)
        for i in range(n):
            for j in range(width):
                with contextlib.suppress(TypeError, ValueError, OverflowError):
                    out[i, j] = float(values[i][j])
        return out


def _ints(stamps: Any, rows: np.ndarray) -> np.ndarray:
    """Stamps of the rows as int64 (ns; those beyond int64 clipped: they only order)."""
    picked = [stamps[i] for i in rows.tolist()] if not isinstance(stamps, np.ndarray) else None
    values = stamps[rows] if picked is None else picked
    try:
        return np.asarray(values, dtype=np.int64)
    except OverflowError:
        return np.asarray([min(int(v), 2**63 - 1) for v in values], dtype=np.int64)
