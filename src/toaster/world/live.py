"""A source fed while running: push poses from sensors (any thread), applied at the next tick.

The newest pose per entity wins, as the original's PDG readers (queue size 1): an entity keeps
at most ``max_pending`` poses not yet applied, so memory never grows with the input rate. A pose
stamped after the tick waits for a later tick. A bad pose (non-finite numbers, empty id, unknown
kind, an id the store would refuse, a stamp out of range) is refused by :meth:`LiveSource.push`
with a one-line reason (``False``; counted in ``rejected`` and in ``drops`` per topic and
field, kept in ``last_error``), never inside the tick. Time going backwards for an
entity by more than ``rewind_ns`` (a restarted sensor) forgets that entity's history, so that
its new poses are taken instead of being ignored as older. Stamps more than ``max_skew_ns`` away
from the tick's clock (simulated time, a looping bag, an unsynchronised machine) are shifted by
one offset per source so that the newest lands on the tick: relative times, hence speeds, stay
exact; each new offset is one warning line. The poses wait as columns
(:mod:`toaster.world.pending`), and :meth:`LiveSource.push_many` buffers a batch (a crowd's /tf
message) checked as arrays, so neither buffering nor a tick loops over entities.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Callable, Sequence

import numpy as np

from toaster.errors import ToasterError
from toaster.model import (
    MAX_COORD,
    check_agent_id,
    check_id,
    check_optional_id,
    check_unit_interval,
    shown,
)
from toaster.timeutil import MAX_NS, NS_PER_S, check_ns, now_ns
from toaster.world.drops import Drops, Refused, refuse_if
from toaster.world.geometry import check_quat, quats_to_rpy
from toaster.world.geometry import quaternion_to_rpy as quaternion_to_rpy  # its old home
from toaster.world.history import NO_TIME
from toaster.world.pending import Pending, Sig
from toaster.world.state import KIND_CODES, World

#: Entities a live world holds at most: a publisher inventing new ids cannot make the world
#: (and the database's entities) grow without end; poses of further new ids are refused.
MAX_LIVE_ENTITIES = 100_000
#: a quaternion's components are refused beyond this (as :func:`_numbers` checks them)
MAX_QUAT = 1e150


def _numbers(values: object, field: str, what: str, bound: float, most: int = 4) -> list[float]:
    """``values`` (at most ``most``) as finite floats within ±``bound``, else
    :class:`Refused` naming them."""
    try:
        out = [float(v) for v in list(values)[: most + 1]]  # type: ignore[call-overload]
    except (TypeError, ValueError, OverflowError):
        out = [math.nan]
    if len(out) > most:
        out.append(math.nan)
    if not all(math.isfinite(v) and abs(v) <= bound for v in out):
        msg = f"{what} {shown(values)} must be finite numbers within ±{bound:g}"
        raise Refused(msg, field)
    return out


def check_entity(entity_id: object, kind: object, owner_id: object = "", joint: object = "") -> str:
    """``entity_id`` if the store will register it as ``kind`` (an agent's id without
    ``>``, a joint with its agent): the checks of :mod:`toaster.model`; else
    :class:`Refused` naming the field (kind, id, owner, joint)."""
    if kind not in KIND_CODES:
        msg = f"unknown kind {shown(kind)} of {shown(entity_id)} (use {', '.join(KIND_CODES)})"
        raise Refused(msg, "kind")
    if kind == "joint":
        if not owner_id:
            msg = f"joint {shown(entity_id)} needs its agent (owner id)"
            raise Refused(msg, "owner")
        refuse_if(check_agent_id, owner_id, "owner", "owner id")
        refuse_if(check_optional_id, joint, "joint", "joint name")
    refuse_if(
        check_agent_id if kind in ("human", "robot") else check_id, entity_id, "id", f"{kind} id"
    )
    return str(entity_id)


def _checked(
    entity_id: object,
    position: Sequence[float],
    yaw: float,
    rpy: Sequence[float] | None,
    quat: Sequence[float] | None,
    t_ns: int | None,
    kind: str,
    confidence: float,
    owner_id: str,
    joint: str,
) -> tuple[str, float, float, float, list[float], int, float]:
    """A pose checked as the store will check it (ids, time, confidence) and as the world
    needs it (finite coordinates within ±MAX_COORD m, an orientation); :class:`Refused`."""
    check_entity(entity_id, kind, owner_id, joint)
    xyz = _numbers(position, "position", "position (m)", MAX_COORD, 3)
    if len(xyz) < 2:
        msg = f"position {shown(position)} needs x, y[, z] (metres)"
        raise Refused(msg, "position")
    x, y, z = [*xyz, 0.0][:3]
    if quat is not None:
        q = _numbers(quat, "orientation", "quaternion", MAX_QUAT)
        try:
            angles = list(check_quat(q))
        except (TypeError, ValueError) as exc:
            raise Refused(str(exc), "orientation") from None
    elif rpy is not None:
        angles = _numbers(rpy, "orientation", "roll, pitch, yaw (rad)", MAX_COORD, 3)
    else:
        angles = [0.0, 0.0, *_numbers([yaw], "orientation", "yaw (rad)", MAX_COORD, 1)]
    if len(angles) != 3 and quat is None:
        msg = f"orientation {shown(angles)} must be roll, pitch, yaw"
        raise Refused(msg, "orientation")
    if isinstance(t_ns, np.integer):
        t_ns = int(t_ns)
    if t_ns is not None:
        refuse_if(check_ns, t_ns, "stamp")
    stamp = now_ns() if t_ns is None else int(t_ns)
    refuse_if(check_unit_interval, confidence, "confidence")
    return (str(entity_id), x, y, z, angles, stamp, float(confidence))


class LiveSource:
    """Thread-safe buffer of the newest poses per entity; ``advance`` applies them."""

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
        self._pending = Pending(self.max_pending)
        # the world row of each interned entity (-1: not looked up yet), for one world
        self._rows = np.zeros(0, np.int64)
        self._world: weakref.ref[World] | None = None
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
        sig = _sig(entity_id, kind, owner_id, joint)
        with self._lock:
            self._pending.add_one(sig, stamp, (x, y, z), tuple(angles), quat is not None, conf)
        if self.on_push is not None:
            self.on_push()
        return True

    def push_many(
        self,
        targets: Sequence[Sig],
        positions: np.ndarray,
        quats: np.ndarray,
        stamps: Sequence[int | None],
        *,
        topic: str | None = None,
    ) -> int:
        """Buffer many poses at once, as :meth:`push` would one by one, in order: ``targets``
        (entity id, kind, owner id, joint name) per pose, world positions (n, 3), quaternions
        (n, 4) (x, y, z, w), integer stamps (None: now), confidence 1. Checked as arrays (a
        signature once); a pose refused goes through :meth:`push` for its reason and count.
        Returns how many were buffered."""
        n = len(targets)
        pos = np.asarray(positions, dtype=float).reshape(n, 3)
        q = np.asarray(quats, dtype=float).reshape(n, 4)
        ok = (np.abs(pos) <= MAX_COORD).all(axis=1) & (np.abs(q) <= MAX_QUAT).all(axis=1)
        x, y, z, w = q.T
        norm = np.sqrt(x * x + y * y + z * z + w * w)  # check_quat's sum, in its order
        ok &= norm != 0.0
        now = now_ns()
        plain = all(type(s) is int or s is None for s in stamps)
        t = np.fromiter(
            ((now if s is None else s if 0 <= s <= MAX_NS else -1) for s in stamps)
            if plain
            else (),
            np.int64,
            n if plain else 0,
        )
        if plain:
            ok &= t >= 0
        else:
            ok[:] = False
        codes = np.full(n, -1, np.int64)
        with self._lock:
            known = self._pending.sig_code
            for i, target in enumerate(targets):
                code = known.get(target)
                if code is None and ok[i]:
                    try:
                        check_entity(*target)
                    except Refused:
                        ok[i] = False
                        continue
                    code = self._pending.code(_sig(*target))
                if code is not None:
                    codes[i] = code
            good = np.flatnonzero(ok)
            if good.size:
                self._pending.add_many(codes[good], t[good], pos[good], q[good] / norm[good, None])
        for i in np.flatnonzero(~ok).tolist():  # each refused for its reason
            entity_id, kind, owner_id, joint = targets[i]
            self.push(
                entity_id,
                positions[i],
                quat=quats[i],
                t_ns=stamps[i],
                kind=kind,
                owner_id=owner_id,
                joint=joint,
                topic=topic,
            )
        if good.size and self.on_push is not None:
            self.on_push()
        return int(good.size)

    def pending(self) -> int:
        """How many poses are buffered, not yet applied (at most ``max_pending`` an
        entity)."""
        with self._lock:
            self._pending.compact()
            return self._pending.count

    def setup(self, world: World) -> None:
        """Nothing to register up front; entities are added when first pushed."""

    def newest_stamp(self, wall_ns: int) -> int | None:
        """The newest stamp (offset added) of the poses a tick at ``wall_ns`` would apply, once
        stamps far from it are shifted (a live node's perception time, docs/time.md)."""
        with self._lock:
            self._align(wall_ns)
            newest = self._pending.newest(wall_ns - self.offset_ns)
            return None if newest is None else newest + self.offset_ns

    def advance(self, world: World, t_ns: int) -> None:
        """Apply, per entity, the newest buffered pose stamped at or before ``t_ns``."""
        with self._lock:
            pending = self._pending
            if not pending.count:
                return
            if pending.forget_unused(world.n) or self._world is None or self._world() is not world:
                self._rows = np.zeros(0, np.int64)
                self._world = weakref.ref(world)
            self._align(t_ns)
            ready = pending.take_due(t_ns - self.offset_ns)
            if not len(ready.sig):
                return
            # agents before their joints; a joint whose agent is unknown waits for it
            first = np.argsort(pending.sig_joint(ready.sig), kind="stable")
            ready = ready.take(first)
            sigs = [pending.sigs[c] for c in ready.sig.tolist()]
            rows = self._world_rows(world, ready.eid)
            eids = ready.eid
        new = np.flatnonzero(rows < 0)
        for i in new.tolist():
            rows[i] = self._add(world, sigs[i])
        if new.size:
            found = rows[new] >= 0
            self._rows[eids[new[found]]] = rows[new[found]]
        applied = np.flatnonzero(rows >= 0)
        if not applied.size:
            return
        ready, rows = ready.take(applied), rows[applied]
        stamps = ready.stamp + self.offset_ns
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
        rpy = ready.orient[:, :3].copy()
        if ready.quat.any():
            rpy[ready.quat] = quats_to_rpy(ready.orient[ready.quat])
        world.observe(self.name, rows, stamps, ready.pos, rpy, ready.conf)

    def _world_rows(self, world: World, eids: np.ndarray) -> np.ndarray:
        """The world rows of entity codes, -1 for those not looked up yet (lock held)."""
        known = len(self._pending.eids)
        if len(self._rows) < known:
            grow = max(known, 2 * len(self._rows), 16) - len(self._rows)
            self._rows = np.concatenate([self._rows, np.full(grow, -1, np.int64)])
        return self._rows[eids].copy()

    def _add(self, world: World, sig: Sig) -> int:
        """The row of an entity the cache does not know: the world's, or a new one; -1 (with
        the reason) when it cannot be added now."""
        eid, kind, owner, joint = sig
        row = world.index.get(eid)
        if row is not None:
            return row
        if len(world.ids) >= self.max_entities:
            self._refuse(
                "id",
                f"pose of {shown(eid)} refused: the world holds "
                f"{self.max_entities} entities already, removed ones "
                "included (MAX_LIVE_ENTITIES)",
                None,
            )
            return -1
        if kind == "joint" and owner not in world.index:
            self.warnings.append(f"joint {eid!r} ignored: its agent {owner!r} is not known yet")
            return -1
        try:
            return world.add_entity(
                eid, kind, owner_id=owner if kind == "joint" else "", name=joint or eid
            )
        except ToasterError as exc:
            self.warnings.append(f"pose of {eid!r} ignored: {exc}")
            return -1

    def _align(self, t_ns: int) -> None:
        """Shift stamps far from the tick's clock (lock held)."""
        newest = self._pending.newest()
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


def _sig(entity_id: str, kind: str, owner_id: object, joint: object) -> Sig:
    """A pose's (entity id, kind, owner id, joint name) as applied: the owner counts for
    joints only; the joint name is also a new entity's name."""
    owner = str(owner_id) if kind == "joint" else ""
    return (entity_id, kind, owner, joint if isinstance(joint, str) else str(joint or ""))
