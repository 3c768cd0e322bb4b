"""LiveSource keeps its pending poses as columns (toaster.world.pending) and applies them with
array operations; the loop per entity it replaced is kept here as the reference: on random
streams (ties, old and future stamps, rewinds, joints before their agents, overflowing queues,
refused poses, batches) both give the same world, rows, warnings and counts."""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence

import numpy as np
import pytest

from toaster.errors import ToasterError
from toaster.model import shown
from toaster.timeutil import NS_PER_S
from toaster.world.drops import Drops, Refused
from toaster.world.geometry import quats_to_rpy
from toaster.world.history import NO_TIME
from toaster.world.live import MAX_LIVE_ENTITIES, LiveSource, _checked
from toaster.world.state import World

_Pose = tuple[str, str, str, str, int, tuple[float, float, float], tuple[float, ...], float]


class ReferenceSource:
    """The loop per entity that :class:`LiveSource` replaced (main @ 1b212f2), verbatim."""

    def __init__(
        self,
        name: str = "live",
        *,
        max_pending: int = 8,
        rewind_ns: int = NS_PER_S,
        max_skew_ns: int = 5 * NS_PER_S,
        drops: Drops | None = None,
        max_entities: int = MAX_LIVE_ENTITIES,
    ) -> None:
        self.name = name
        self.max_entities = int(max_entities)
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self.max_pending = max(1, int(max_pending))
        self.rewind_ns = int(rewind_ns)
        self.max_skew_ns = int(max_skew_ns)
        self.offset_ns = 0  # added to every stamp (see the module's doc)
        self.rejected = 0
        self.last_error = ""
        self.drops = drops if drops is not None else Drops()
        self.warnings: list[str] = []  # one line per problem met while applying (drained)
        self._lock = threading.Lock()
        self._pending: dict[str, list[_Pose]] = {}
        #: called after each accepted pose (a live node sets it to wake its loop)
        self.on_push: Callable[[], None] | None = None

    def _refuse(self, field: str, reason: str, topic: str | None) -> bool:
        with self._lock:
            self.rejected += 1
            self.last_error = reason
        self.drops.drop(topic or self.name, field, reason)
        return False

    def push(
        self,
        entity_id: str,
        position: Sequence[float],
        *,
        yaw: float = 0.0,
        rpy: Sequence[float] | None = None,
        quat: Sequence[float] | None = None,
        t_ns: int | None = None,
        kind: str = "human",
        confidence: float = 1.0,
        owner_id: str = "",
        joint: str = "",
        topic: str | None = None,
    ) -> bool:
        """Buffer a pose (x, y[, z] in metres; orientation as yaw, rpy or a quaternion x, y, z,
        w; time defaults to the wall clock). Joints: ``kind="joint"`` with ``owner_id`` and the
        skeleton name ``joint``, position in world coordinates. False (with ``last_error``,
        counted in ``drops`` under ``topic``, default the source's name) when the pose is
        refused: the store's checks of ids, times and confidences, finite coordinates within
        ±MAX_COORD."""
        try:
            pose = _checked(
                entity_id, position, yaw, rpy, quat, t_ns, kind, confidence, owner_id, joint
            )
        except Refused as exc:
            return self._refuse(exc.field, f"pose of {shown(entity_id)} refused: {exc}", topic)
        entity_id, x, y, z, angles, stamp, conf = pose
        item: _Pose = (
            entity_id,
            kind,
            owner_id,
            joint,
            stamp,
            (x, y, z),
            tuple(angles),
            conf,
        )
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

    def newest_stamp(self, wall_ns: int) -> int | None:
        """The newest stamp (offset added) of the poses a tick at ``wall_ns`` would apply, once
        stamps far from it are shifted (a live node's perception time, docs/time.md)."""
        with self._lock:
            self._align(wall_ns)
            off = self.offset_ns
            due = (p[4] + off for q in self._pending.values() for p in q if p[4] + off <= wall_ns)
            return max(due, default=None)

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
                if len(world.ids) >= self.max_entities:
                    self._refuse(
                        "id",
                        f"pose of {shown(eid)} refused: the world holds "
                        f"{self.max_entities} entities already, removed ones "
                        "included (MAX_LIVE_ENTITIES)",
                        None,
                    )
                    continue
                if kind == "joint" and owner not in world.index:
                    self.warnings.append(
                        f"joint {eid!r} ignored: its agent {owner!r} is not known yet"
                    )
                    continue
                try:
                    world.add_entity(
                        eid, kind, owner_id=owner if kind == "joint" else "", name=joint or eid
                    )
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
                self.warnings.append(
                    f"time went backwards for {world.ids[r]!r}: its history was reset"
                )
            world.history.clear_rows(back)
            world.t_ns[back] = NO_TIME
        rpy = np.zeros((len(applied), 3))
        turned = [i for i, p in enumerate(applied) if len(p[6]) == 4]
        rpy[turned] = quats_to_rpy([applied[i][6] for i in turned])
        angles = [i for i, p in enumerate(applied) if len(p[6]) == 3]
        if angles:
            rpy[angles] = [applied[i][6] for i in angles]
        world.observe(
            self.name,
            rows,
            stamps,
            np.array([p[5] for p in applied]),
            rpy,
            np.array([p[7] for p in applied]),
        )

    def _align(self, t_ns: int) -> None:
        """Shift stamps far from the tick's clock (lock held)."""
        newest = max((p[4] for queue in self._pending.values() for p in queue), default=None)
        if newest is None or abs(newest + self.offset_ns - t_ns) <= self.max_skew_ns:
            return
        self.offset_ns = t_ns - newest
        self.warnings.append(
            f"stamps are {abs(self.offset_ns) / NS_PER_S:.1f} s "
            f"{'behind' if self.offset_ns > 0 else 'ahead of'} the node's "
            "clock (simulated time, a looping bag or an unsynchronised "
            "clock?): shifted to it; play bags with --clock and use_sim_time, synchronise "
            "clocks (NTP)"
        )

    def take_warnings(self) -> list[str]:
        """The warnings met while applying since the last call (refused pushes are reported
        by ``drops``)."""
        with self._lock:
            out, self.warnings = self.warnings, []
        return out


IDS = [("bob", "human", "", ""), ("ann", "human", "", ""), ("r2", "robot", "", "")]
IDS += [("cup", "object", "", ""), ("mug", "object", "", ""), ("box", "object", "", "x")]
IDS += [("bob/head", "joint", "bob", "head"), ("ann/hand", "joint", "ann", "hand")]
IDS += [("zed/head", "joint", "zed", "head"), ("zed", "human", "", "")]
IDS += [("", "object", "", ""), ("a>b", "human", "", ""), ("dragon", "dragon", "", "")]


def _state(world: World) -> tuple:
    n = world.n
    return (
        list(world.ids),
        list(world.kind_text),
        list(world.names),
        world.owner[:n].tolist(),
        world.pos[:n].tolist(),
        world.rpy[:n].tolist(),
        world.t_ns[:n].tolist(),
        world.conf[:n].tolist(),
        world.active[:n].tolist(),
        world.history.t[:n].tolist(),
    )


def _stream(seed: int, new: LiveSource, ref: ReferenceSource, steps: int = 300) -> None:
    rng = np.random.default_rng(seed)
    worlds = World(), World()
    base = 10**12
    t = base
    for _ in range(steps):
        op = rng.random()
        if op < 0.5:
            entity, kind, owner, joint = IDS[rng.integers(len(IDS))]
            stamp = int(t + rng.integers(-3, 3) * 10**8) if rng.random() < 0.9 else None
            if rng.random() < 0.03:
                stamp = int(t - 5 * NS_PER_S)  # a rewind
            pos = rng.normal(0, 2, 3).round(2).tolist()
            if rng.random() < 0.05:
                pos[0] = math.nan
            args: dict = {"t_ns": stamp, "kind": kind, "owner_id": owner, "joint": joint}
            if rng.random() < 0.5:
                args["quat"] = rng.normal(0, 1, 4).tolist()
            else:
                args["rpy"] = rng.normal(0, 1, 3).tolist()
            if rng.random() < 0.1:
                args["confidence"] = float(rng.random())
            if stamp is None:  # the wall clock differs between the two: give one
                args["t_ns"] = int(t)
            assert new.push(entity, pos, **args) == ref.push(entity, pos, **args)
        elif op < 0.65:
            k = int(rng.integers(1, 12))
            picks = [IDS[i] for i in rng.integers(len(IDS), size=k)]
            pos = rng.normal(0, 2, (k, 3)).round(2)
            quats = rng.normal(0, 1, (k, 4))
            if rng.random() < 0.2:
                quats[0] = 0.0
            stamps = [int(t + d * 10**8) for d in rng.integers(-3, 3, k)]
            accepted = new.push_many(picks, pos, quats, stamps, topic="/tf")
            expected = sum(
                ref.push(
                    e,
                    pos[i],
                    quat=quats[i],
                    t_ns=stamps[i],
                    kind=kd,
                    owner_id=o,
                    joint=j,
                    topic="/tf",
                )
                for i, (e, kd, o, j) in enumerate(picks)
            )
            assert accepted == expected
        elif op < 0.7:
            assert new.newest_stamp(int(t)) == ref.newest_stamp(int(t))
        else:
            t += int(rng.integers(0, 3)) * 10**8
            new.advance(worlds[0], int(t))
            ref.advance(worlds[1], int(t))
            worlds[0].commit()
            worlds[1].commit()
            assert _state(worlds[0]) == _state(worlds[1])
            assert new.take_warnings() == ref.take_warnings()
            assert new.offset_ns == ref.offset_ns
        assert (new.rejected, new.last_error) == (ref.rejected, ref.last_error)
        assert new.drops.counts() == ref.drops.counts()


@pytest.mark.parametrize("seed", range(40))
def test_columns_apply_what_the_loop_per_entity_applied(seed):
    _stream(seed, LiveSource(max_pending=4), ReferenceSource(max_pending=4))


def test_a_small_world_refuses_new_ids_as_the_loop_did():
    new = LiveSource(max_entities=4)
    ref = ReferenceSource(max_entities=4)
    _stream(7, new, ref, steps=200)


def test_a_crowded_queue_keeps_the_newest_and_ids_are_forgotten():
    """1000 poses of one entity keep max_pending; 20,000 invented ids refused by a full world
    do not stay interned."""
    src = LiveSource(max_entities=10)
    for k in range(1000):
        src.push("bob", (k / 1000, 0, 0), t_ns=10**12 - 1000 + k)
    assert src.pending() == src.max_pending
    world = World()
    src.advance(world, 10**12)
    assert world.pos[world.row("bob"), 0] == pytest.approx(0.999)
    for k in range(20_000):
        src.push(f"ghost{k}", (0, 0, 0), t_ns=10**12 + 10**9, kind="object")
    src.advance(world, 10**12)  # none due yet
    assert len(src._pending.sigs) == 20_000
    src.advance(world, 10**12 + 2 * 10**9)
    src.push("bob", (1, 0, 0), t_ns=10**12 + 3 * 10**9)
    src.advance(world, 10**12 + 3 * 10**9)
    assert len(src._pending.sigs) <= 1
    assert world.pos[world.row("bob"), 0] == 1.0
    assert world.n == 10
    assert src.drops.counts() == {"live id": 20_000 - 9}
