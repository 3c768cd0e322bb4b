"""A source fed while running: push poses from sensors (any thread), applied at the next tick.

The newest pose per entity wins, as the original's PDG readers (queue size 1): an entity keeps
at most ``max_pending`` poses not yet applied, so memory never grows with the input rate. A pose
stamped after the tick waits for a later tick. A bad pose (non-finite numbers, empty id, unknown
kind) is refused by :meth:`LiveSource.push` with a one-line reason (``False``; counted in
``rejected`` and kept in ``last_error``), never inside the tick. Time going backwards for an
entity by more than ``rewind_ns`` (a restarted sensor) forgets that entity's history, so that
its new poses are taken instead of being ignored as older. Stamps more than ``max_skew_ns`` away
from the tick's clock (simulated time, a looping bag, an unsynchronised machine) are shifted by
one offset per source so that the newest lands on the tick: relative times, hence speeds, stay
exact; each new offset is one warning line.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence

import numpy as np

from toaster.errors import ToasterError
from toaster.timeutil import NS_PER_S, now_ns
from toaster.world.history import NO_TIME
from toaster.world.state import KIND_CODES, World

#: (entity id, kind, owner id, joint name, t_ns, position, rpy, confidence)
_Pose = tuple[str, str, str, str, int, tuple[float, float, float], tuple[float, float, float],
              float]


def quaternion_to_rpy(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """Roll, pitch, yaw (radians, ZYX as ROS) of a quaternion; it need not be normalised."""
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or norm == 0.0:
        msg = f"quaternion ({x}, {y}, {z}, {w}) has no orientation: give a non-zero quaternion"
        raise ValueError(msg)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


class LiveSource:
    """Thread-safe buffer of the newest poses per entity; ``advance`` applies them."""

    def __init__(self, name: str = "live", *, max_pending: int = 8,
                 rewind_ns: int = NS_PER_S, max_skew_ns: int = 5 * NS_PER_S) -> None:
        self.name = name
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self.max_pending = max(1, int(max_pending))
        self.rewind_ns = int(rewind_ns)
        self.max_skew_ns = int(max_skew_ns)
        self.offset_ns = 0  # added to every stamp (see the module's doc)
        self.rejected = 0
        self.last_error = ""
        self.warnings: list[str] = []  # one line per problem met while applying (drained)
        self._lock = threading.Lock()
        self._pending: dict[str, list[_Pose]] = {}
        #: called after each accepted pose (a live node sets it to wake its loop)
        self.on_push: Callable[[], None] | None = None

    def _refuse(self, reason: str) -> bool:
        with self._lock:
            self.rejected += 1
            self.last_error = reason
        return False

    def push(self, entity_id: str, position: Sequence[float], *, yaw: float = 0.0,
             rpy: Sequence[float] | None = None, quat: Sequence[float] | None = None,
             t_ns: int | None = None, kind: str = "human", confidence: float = 1.0,
             owner_id: str = "", joint: str = "") -> bool:
        """Buffer a pose (x, y[, z] in metres; orientation as yaw, rpy or a quaternion x, y, z,
        w; time defaults to the wall clock). Joints: ``kind="joint"`` with ``owner_id`` and the
        skeleton name ``joint``, position in world coordinates. False (with ``last_error``) when
        the pose is refused."""
        if not isinstance(entity_id, str) or not entity_id.strip():
            return self._refuse(f"pose refused: empty entity id {entity_id!r}")
        if kind not in KIND_CODES:
            return self._refuse(f"pose of {entity_id!r} refused: unknown kind {kind!r} "
                                f"(use {', '.join(KIND_CODES)})")
        if kind == "joint" and not owner_id:
            return self._refuse(f"joint pose {entity_id!r} refused: it needs its agent "
                                "(owner_id)")
        try:
            x, y, z = [*map(float, position), 0.0, 0.0][:3]
            if quat is not None:
                qx, qy, qz, qw = map(float, quat)
                angles = list(quaternion_to_rpy(qx, qy, qz, qw))
            elif rpy is not None:
                angles = [float(a) for a in rpy]
            else:
                angles = [0.0, 0.0, float(yaw)]
            stamp = now_ns() if t_ns is None else int(t_ns)
            conf = float(confidence)
        except (TypeError, ValueError) as exc:
            return self._refuse(f"pose of {entity_id!r} refused: {exc}")
        if len(angles) != 3 or not all(math.isfinite(v) for v in (x, y, z, *angles, conf)):
            return self._refuse(f"pose of {entity_id!r} refused: position {[x, y, z]} / angles "
                                f"{angles} must be finite numbers (metres, radians)")
        item: _Pose = (entity_id, kind, owner_id, joint, stamp, (x, y, z),
                       (angles[0], angles[1], angles[2]), conf)
        with self._lock:
            queue = self._pending.setdefault(entity_id, [])
            queue.append(item)
            if len(queue) > self.max_pending:
                queue.sort(key=lambda p: p[4])
                del queue[: len(queue) - self.max_pending]
        if self.on_push is not None:
            self.on_push()
        return True

    def setup(self, world: World) -> None:
        """Nothing to register up front; entities are added when first pushed."""

    def advance(self, world: World, t_ns: int) -> None:
        """Apply, per entity, the newest buffered pose stamped at or before ``t_ns``."""
        with self._lock:
            self._align(t_ns)
            ready: list[_Pose] = []
            for eid in list(self._pending):
                queue = self._pending[eid]
                due = [p for p in queue if p[4] + self.offset_ns <= t_ns]
                if not due:
                    continue
                ready.append(max(due, key=lambda p: p[4]))
                later = [p for p in queue if p[4] + self.offset_ns > t_ns]
                if later:
                    self._pending[eid] = later
                else:
                    del self._pending[eid]
        if not ready:
            return
        # agents before their joints; a joint whose agent is unknown waits for it
        ready.sort(key=lambda p: p[1] == "joint")
        applied: list[_Pose] = []
        for pose in ready:
            eid, kind, owner, joint = pose[:4]
            if eid not in world.index:
                if kind == "joint" and owner not in world.index:
                    self.warnings.append(f"joint {eid!r} ignored: its agent {owner!r} is not "
                                         "known yet")
                    continue
                try:
                    world.add_entity(eid, kind, owner_id=owner if kind == "joint" else "",
                                     name=joint or eid)
                except ToasterError as exc:
                    self.warnings.append(f"pose of {eid!r} ignored: {exc}")
                    continue
            applied.append(pose)
        if not applied:
            return
        rows = world.rows_of([p[0] for p in applied])
        stamps = np.array([p[4] for p in applied], np.int64) + self.offset_ns
        known = world.t_ns[rows]
        rewound = (known != NO_TIME) & (known > stamps + self.rewind_ns)
        if rewound.any():
            back = rows[rewound]
            for r in back.tolist():
                self.warnings.append(f"time went backwards for {world.ids[r]!r}: its history "
                                     "was reset")
            world.history.clear_rows(back)
            world.t_ns[back] = NO_TIME
        world.observe(self.name, rows, stamps, np.array([p[5] for p in applied]),
                      np.array([p[6] for p in applied]), np.array([p[7] for p in applied]))

    def _align(self, t_ns: int) -> None:
        """Shift stamps far from the tick's clock (lock held)."""
        newest = max((p[4] for queue in self._pending.values() for p in queue), default=None)
        if newest is None or abs(newest + self.offset_ns - t_ns) <= self.max_skew_ns:
            return
        self.offset_ns = t_ns - newest
        self.warnings.append(f"stamps are {abs(self.offset_ns) / NS_PER_S:.1f} s "
                             f"{'behind' if self.offset_ns > 0 else 'ahead of'} the node's "
                             "clock (simulated time, a looping bag or an unsynchronised "
                             "clock?): shifted to it")

    def take_warnings(self) -> list[str]:
        """The warnings met since the last call (and refused pushes, once each)."""
        with self._lock:
            out, self.warnings = self.warnings, []
            if self.last_error:
                out.append(self.last_error)
                self.last_error = ""
        return out
