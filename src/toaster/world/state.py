"""The world model: every entity's current pose as columns of numpy arrays, plus its history.

Rows are stable: an entity keeps its row for the life of the world (leaving only clears
``active``). Joints are stored relative to their agent (``local_pos``/``local_rpy``) and their
world pose is recomputed from the agent on :meth:`World.commit`, so they move rigidly with it
(only where the agent's pose, the local pose or the joint's world pose changed since they
last agreed: a joint observed in world coordinates keeps the pose observed). Objects held in
a hand take the hand's pose.

Several sources may report one entity. Rule: the observation with the newest perception time
wins; on equal times, the most confident one; on equal confidence, the one applied last.
Disabled sources are ignored (the original's ``manage_stream``).
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from toaster.errors import InvalidInputError, UnknownEntityError
from toaster.world.geometry import from_frames, to_frames
from toaster.world.history import DEFAULT_HORIZON_NS, NO_TIME, History

KIND_CODES = {"human": 0, "robot": 1, "object": 2, "joint": 3}
HUMAN, ROBOT, OBJECT, JOINT = 0, 1, 2, 3
MOBILITIES = ("full", "limited", "wheeled", "no")


@dataclass
class Observation:
    """One reported pose of one entity (rpy in radians, time in ns)."""

    entity_id: str
    t_ns: int
    position: Sequence[float]
    rpy: Sequence[float] = (0.0, 0.0, 0.0)
    confidence: float = 1.0


class EntityPose(NamedTuple):
    """One entity in a recording frame: position (m), yaw / roll / pitch (rad), box size (m,
    None: the kind's default), a joint's agent (``owner``) and skeleton name (``name``; else the
    display name), the hand joint holding an object, its perception time (None: the frame's)."""

    id: str
    kind: str
    x: float
    y: float
    z: float
    yaw: float
    roll: float = 0.0
    pitch: float = 0.0
    size: tuple[float, float, float] | None = None
    owner: str = ""
    name: str = ""
    held_by: str = ""
    t_ns: int | None = None


#: World's per-row columns (numpy arrays of at least ``n`` rows)
_COLUMNS = (
    "kind",
    "owner",
    "pos",
    "rpy",
    "local_pos",
    "local_rpy",
    "size",
    "t_ns",
    "conf",
    "active",
    "held_by",
    "_agreed",
)


class World:
    """Current state of all entities (columns) with a per-entity time-bounded history."""

    def __init__(
        self, history_capacity: int = 100, history_horizon_ns: int = DEFAULT_HORIZON_NS
    ) -> None:
        self.ids: list[str] = []
        self.index: dict[str, int] = {}
        self.kind_text: list[str] = []
        self.names: list[str] = []
        self.joint_names: list[str] = []
        self.mobility: list[str] = []
        self.n = 0
        self._cap = 0
        self.kind = np.zeros(0, np.int8)
        self.owner = np.zeros(0, np.int64)
        self.pos = np.zeros((0, 3))
        self.rpy = np.zeros((0, 3))
        self.local_pos = np.zeros((0, 3))
        self.local_rpy = np.zeros((0, 3))
        self.size = np.zeros((0, 3))
        self.t_ns = np.zeros(0, np.int64)
        self.conf = np.zeros(0)
        self.active = np.zeros(0, bool)
        self.held_by = np.zeros(0, np.int64)
        # per joint: the agent's pose, the local pose and the world pose when they last agreed
        # (NaN: never), so that commit recomputes only the joints where one of them changed
        self._agreed = np.zeros((0, 18))
        self.sources_enabled: dict[str, bool] = {}
        self.roles: dict[str, str] = {}  # spatial shape roles: "support" | "container"
        self.closed: dict[str, bool] = {}  # containers that are closed (lid on)
        self.history = History(history_capacity, history_horizon_ns)
        self._version = 0
        self._id_cache: tuple[int, np.ndarray, np.ndarray] = (
            -1,
            np.zeros(0, object),
            np.zeros(0, object),
        )

    def snapshot(self) -> World:
        """A copy of the current state for a reader on another thread (the Foxglove
        publisher): the columns of the live rows and the id lists copied, so that the ticks
        that follow do not change it; the history is shared (not for reading)."""
        view = copy.copy(self)
        n = view.n = self.n
        view._cap = n
        for name in _COLUMNS:
            setattr(view, name, getattr(self, name)[:n].copy())
        view.ids, view.index = list(self.ids), dict(self.index)
        view.kind_text, view.names = list(self.kind_text), list(self.names)
        view.joint_names, view.mobility = list(self.joint_names), list(self.mobility)
        view.sources_enabled, view.roles = dict(self.sources_enabled), dict(self.roles)
        view.closed = dict(self.closed)
        return view

    # -- entities ---------------------------------------------------------------------------
    def _grow(self) -> None:
        cap = max(16, 2 * self._cap)

        def grow(arr: np.ndarray, fill: object) -> np.ndarray:
            extra = np.full((cap - self._cap, *arr.shape[1:]), fill, dtype=arr.dtype)
            return np.concatenate([arr, extra])

        self.kind = grow(self.kind, OBJECT)
        self.owner = grow(self.owner, -1)
        self.pos, self.rpy = grow(self.pos, 0.0), grow(self.rpy, 0.0)
        self.local_pos, self.local_rpy = grow(self.local_pos, 0.0), grow(self.local_rpy, 0.0)
        self.size = grow(self.size, np.nan)
        self.t_ns = grow(self.t_ns, NO_TIME)
        self.conf = grow(self.conf, 0.0)
        self.active = grow(self.active, False)
        self.held_by = grow(self.held_by, -1)
        self._agreed = grow(self._agreed, np.nan)
        self._cap = cap

    def add_entity(
        self,
        entity_id: str,
        kind: str = "object",
        *,
        owner_id: str = "",
        name: str = "",
        size: Sequence[float] | None = None,
        mobility: str = "full",
    ) -> int:
        """Register (or re-activate) an entity and return its row.

        A joint needs ``owner_id`` (its agent); its ``name`` is the skeleton name ("head").
        """
        if not entity_id or not isinstance(entity_id, str):
            msg = f"invalid entity id {entity_id!r}: give a non-empty text id"
            raise InvalidInputError(msg)
        kind = kind.lower()
        if kind not in KIND_CODES:
            msg = (
                f"unknown entity kind {kind!r} for {entity_id!r}: use human, robot, object or joint"
            )
            raise InvalidInputError(msg)
        if mobility not in MOBILITIES:
            msg = f"unknown mobility {mobility!r} for {entity_id!r}: use one of {MOBILITIES}"
            raise InvalidInputError(msg)
        owner = -1
        if kind == "joint":
            owner = self.index.get(owner_id, -1)
            if owner < 0 or self.kind[owner] not in (HUMAN, ROBOT):
                msg = (
                    f"joint {entity_id!r} names owner {owner_id!r}, which is not a known "
                    "human or robot: add the agent first"
                )
                raise UnknownEntityError(msg)
        row = self.index.get(entity_id)
        if row is None:
            if self.n == self._cap:
                self._grow()
            row = self.n
            self.n += 1
            self.ids.append(entity_id)
            self.index[entity_id] = row
            self.kind_text.append(kind)
            self.names.append(name or entity_id)
            self.joint_names.append(name if kind == "joint" else "")
            self.mobility.append(mobility)
        self.kind[row] = KIND_CODES[kind]
        self.owner[row] = owner
        self._version += 1
        if size is not None:
            self.size[row] = size
        self.active[row] = True
        return row

    def remove_entity(self, entity_id: str) -> None:
        """Make an entity (and, for an agent, its joints) leave the world."""
        row = self.row(entity_id)
        rows = np.flatnonzero((np.arange(self._cap) == row) | (self.owner == row))
        self.active[rows] = False
        self.held_by[self.held_by == row] = -1
        self.held_by[np.isin(self.held_by, rows)] = -1
        self.held_by[rows] = -1
        self.t_ns[rows] = NO_TIME
        self.history.clear_rows(rows[rows < self.history.t.shape[0]])

    @property
    def version(self) -> int:
        """Moves whenever an entity is added or comes back (what depends on ids, kinds and
        owners is cached against it)."""
        return self._version

    def _ids_cached(self) -> tuple[int, np.ndarray, np.ndarray]:
        if self._id_cache[0] != self._version:
            ids = np.asarray(self.ids, dtype=object).reshape(-1)
            owner = self.owner[: self.n]
            owners = np.where(owner >= 0, ids[owner], "") if self.n else ids
            self._id_cache = (self._version, ids, np.asarray(owners, dtype=object))
        return self._id_cache

    def id_array(self) -> np.ndarray:
        """Entity ids by row, as a numpy object array (cached until an entity is added)."""
        return self._ids_cached()[1]

    def owner_id_array(self) -> np.ndarray:
        """Owner id by row ("" for entities without owner), as a numpy object array."""
        return self._ids_cached()[2]

    def row(self, entity_id: str) -> int:
        """Row of a known entity, or a one-line error naming it."""
        try:
            return self.index[entity_id]
        except KeyError:
            msg = f"unknown entity {entity_id!r}: add it (scenario 'entities' or add_entity) first"
            raise UnknownEntityError(msg) from None

    def joint_of(self, agent_id: str, joint_name: str) -> int:
        """Row of an agent's joint found by skeleton name (or id), -1 when it has none."""
        agent = self.index.get(agent_id, -1)
        if agent < 0:
            return -1
        for row in np.flatnonzero(self.owner[: self.n] == agent):
            if self.joint_names[row] == joint_name or self.ids[row] == joint_name:
                return int(row)
        return -1

    # -- observations -----------------------------------------------------------------------
    def set_source_enabled(self, source: str, enabled: bool) -> None:
        """Switch a source on or off (observations of a disabled source are dropped)."""
        self.sources_enabled[source] = bool(enabled)

    def observe(
        self,
        source: str,
        ids: Sequence[str] | np.ndarray,
        t_ns: Sequence[int] | np.ndarray,
        pos: np.ndarray,
        rpy: np.ndarray | None = None,
        conf: np.ndarray | None = None,
    ) -> int:
        """Apply a batch of poses from one source with the newest-then-most-confident rule.

        Unknown ids must have been added first. ``ids`` may also be an integer array of
        rows (see :meth:`rows_of`), which skips the id lookups. Joint poses are given in world
        coordinates and stored relative to their agent. Returns how many entities changed.
        """
        if not self.sources_enabled.setdefault(source, True) or len(ids) == 0:
            return 0
        if isinstance(ids, np.ndarray) and ids.dtype.kind in "iu":
            rows = ids.astype(np.int64, copy=False)
            if rows.min() < 0 or rows.max() >= self.n:
                msg = f"source {source!r} reports rows outside the world (0..{self.n - 1})"
                raise UnknownEntityError(msg)
        else:
            try:
                rows = np.fromiter((self.index[i] for i in ids), np.int64, len(ids))
            except KeyError as exc:
                msg = f"source {source!r} reports unknown entity {exc.args[0]!r}: add it first"
                raise UnknownEntityError(msg) from None
        t = np.asarray(t_ns, dtype=np.int64)
        pos = np.asarray(pos, dtype=float).reshape(-1, 3)
        rpy = np.zeros_like(pos) if rpy is None else np.asarray(rpy, float).reshape(-1, 3)
        conf = np.ones(len(rows)) if conf is None else np.asarray(conf, dtype=float)
        if not (np.isfinite(pos).all() and np.isfinite(rpy).all()):
            msg = f"source {source!r} sent a non-finite pose: send metres and radians only"
            raise InvalidInputError(msg)
        order = np.lexsort((conf, t, rows))
        last = np.ones(len(order), bool)
        last[:-1] = rows[order][1:] != rows[order][:-1]
        pick = order[last]
        r, t, c = rows[pick], t[pick], conf[pick]
        wins = (t > self.t_ns[r]) | ((t == self.t_ns[r]) & (c >= self.conf[r]))
        r, pick = r[wins], pick[wins]
        self.pos[r] = pos[pick]
        self.rpy[r] = rpy[pick]
        self.t_ns[r] = t[wins]
        self.conf[r] = c[wins]
        self.active[r] = True
        joints = r[self.kind[r] == JOINT]
        if joints.size:
            self._set_local_from_world(joints)
        return int(r.size)

    def set_pose(
        self,
        entity_id: str,
        position: Sequence[float],
        t_ns: int,
        rpy: Sequence[float] = (0.0, 0.0, 0.0),
        *,
        source: str = "api",
        confidence: float = 1.0,
    ) -> None:
        """Set one entity's world pose (a convenience over :meth:`observe`)."""
        self.observe(
            source,
            [entity_id],
            [t_ns],
            np.asarray([position], float),
            np.asarray([rpy], float),
            np.asarray([confidence]),
        )

    def set_joint_local(
        self,
        joint_id: str,
        position: Sequence[float],
        rpy: Sequence[float] = (0.0, 0.0, 0.0),
        t_ns: int | None = None,
    ) -> None:
        """Set a joint's pose relative to its agent (x forward, y left, z up)."""
        row = self.row(joint_id)
        if self.kind[row] != JOINT:
            msg = f"{joint_id!r} is not a joint: only joints have a pose relative to an agent"
            raise InvalidInputError(msg)
        self.local_pos[row] = position
        self.local_rpy[row] = rpy
        if t_ns is not None:
            self.t_ns[row] = max(int(self.t_ns[row]), t_ns)

    def _set_local_from_world(self, joints: np.ndarray) -> None:
        agents, parents = np.unique(self.owner[joints], return_inverse=True)
        self.local_pos[joints], self.local_rpy[joints] = to_frames(
            self.pos[agents], self.rpy[agents], self.pos[joints], self.rpy[joints], parents
        )
        self._agreed[joints] = self._joint_poses(joints)

    def _joint_poses(self, joints: np.ndarray) -> np.ndarray:
        """(n, 18): each joint's agent's pose, its local pose and its world pose."""
        agents = self.owner[joints]
        return np.hstack(
            [
                self.pos[agents],
                self.rpy[agents],
                self.local_pos[joints],
                self.local_rpy[joints],
                self.pos[joints],
                self.rpy[joints],
            ]
        )

    def set_shape(
        self,
        entity_id: str,
        *,
        size: Sequence[float] | None = None,
        role: str | None = None,
        closed: bool | None = None,
    ) -> None:
        """Give an entity a box (size x, y, z in metres), a role (support, container) or a lid."""
        row = self.row(entity_id)
        if size is not None:
            self.size[row] = size
        if role is not None:
            if role not in ("support", "container", "none"):
                msg = f"unknown shape role {role!r} for {entity_id!r}: use support or container"
                raise InvalidInputError(msg)
            self.roles[entity_id] = role
        if closed is not None:
            self.closed[entity_id] = bool(closed)

    # -- held objects -----------------------------------------------------------------------
    def put_in_hand(self, object_id: str, agent_id: str, hand: str) -> None:
        """Attach an object to an agent's hand joint: it follows the hand until removed."""
        obj = self.row(object_id)
        joint = self.joint_of(agent_id, hand)
        if joint < 0:
            msg = f"agent {agent_id!r} has no joint {hand!r}: declare it under the agent's joints"
            raise UnknownEntityError(msg)
        self.held_by[obj] = joint

    def remove_from_hand(self, object_id: str) -> None:
        """Release an object; it stays where it last was."""
        self.held_by[self.row(object_id)] = -1

    def busy_hands(self, agent_id: str) -> list[str]:
        """Ids of the agent's joints that hold something."""
        agent = self.row(agent_id)
        held = self.held_by[: self.n]
        hands = {int(h) for h in held[held >= 0] if self.owner[h] == agent}
        return sorted(self.ids[h] for h in hands)

    def held_objects(self, agent_id: str) -> list[str]:
        """Ids of the objects an agent holds."""
        agent = self.row(agent_id)
        held = self.held_by[: self.n]
        rows = np.flatnonzero(held >= 0)
        return sorted(self.ids[r] for r in rows if self.owner[held[r]] == agent)

    # -- tick -------------------------------------------------------------------------------
    def commit(self) -> None:
        """Recompute joints from their agents and held objects from their hands; record history."""
        n = self.n
        joints = np.flatnonzero(self.kind[:n] == JOINT)
        if joints.size:
            agents = self.owner[joints]
            moved = joints[(self._joint_poses(joints) != self._agreed[joints]).any(axis=1)]
            if moved.size:
                parents_of, parents = np.unique(self.owner[moved], return_inverse=True)
                self.pos[moved], self.rpy[moved] = from_frames(
                    self.pos[parents_of],
                    self.rpy[parents_of],
                    self.local_pos[moved],
                    self.local_rpy[moved],
                    parents,
                )
                self._agreed[moved] = self._joint_poses(moved)
            self.t_ns[joints] = np.maximum(self.t_ns[joints], self.t_ns[agents])
        held = np.flatnonzero(self.held_by[:n] >= 0)
        if held.size:
            hands = self.held_by[held]
            self.pos[held] = self.pos[hands]
            self.rpy[held] = self.rpy[hands]
            self.t_ns[held] = np.maximum(self.t_ns[held], self.t_ns[hands])
        rows = np.flatnonzero(self.active[:n])
        self.history.append(self.t_ns[:n], self.pos[:n], self.rpy[:n], rows)

    def live_mask(self, t_ns: int, presence_timeout_ns: int | None) -> np.ndarray:
        """Active entities, minus agents (and their joints) not perceived within the timeout."""
        n = self.n
        live = self.active[:n] & (self.t_ns[:n] != NO_TIME)
        if presence_timeout_ns is not None:
            agent = self.kind[:n] <= ROBOT
            stale = agent & (t_ns - self.t_ns[:n] > presence_timeout_ns)
            live &= ~stale
            joints = np.flatnonzero(self.kind[:n] == JOINT)
            live[joints] &= live[self.owner[joints]]
        return live

    def rows_of(self, ids: Iterable[str]) -> np.ndarray:
        """Rows of known ids (unknown ids are skipped)."""
        return np.asarray([self.index[i] for i in ids if i in self.index], dtype=np.int64)
