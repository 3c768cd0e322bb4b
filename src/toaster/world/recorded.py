"""What a toaster recording carries besides the ROS topics, so that ``toaster run`` on it
reproduces the run: how the run was set up (``/toaster/run``, :class:`RunInfo`) and the world
the producers saw at every tick (``/toaster/world``, :func:`world_fields`), replayed exactly by
:class:`WorldReplay`.

pdg's entity lists and /tf draw the world for viewers, but they have no sizes, shape roles,
lids or held objects, turn every angle into a quaternion and say nothing of the self agent,
the belief holders or the thresholds. The two messages below hold those, in float64, so a
replay computes the same facts bit for bit. Both types travel in the bag (``toaster_recording``
package, as the belief channels).
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toaster.errors import InvalidInputError
from toaster.world.state import JOINT, KIND_CODES, World

RUN_TOPIC, WORLD_TOPIC = "/toaster/run", "/toaster/world"
RUN_TYPE, WORLD_TYPE = "toaster_recording/msg/Run", "toaster_recording/msg/World"
RUN_MSG = """\
# How the toaster run that made this recording was set up (written once, at its start):
# `toaster run` on the recording replays it with these.
std_msgs/Header header
# The self agent (the robot whose beliefs are the world state).
string self_id
# Which humans hold beliefs: "humans", "none" or a JSON list of ids.
string holders_json
# The producers' thresholds (docs/producers.md), "spatial" included, as JSON.
string config_json
# The areas as `toaster area add` takes them, {id: spec}, as JSON (exact; AreaList rounds).
string areas_json
# The store's belief settings that differ from the defaults, {key: value}, as JSON.
string settings_json
# The entities of the run's world in row order (never perceived ones included).
string[] ids
string[] kinds
string[] names
string[] owners
string[] mobility
# Whether the agents got their per-agent views (fact_table_<id>).
bool agent_views
# The run's last tick time, and its tick rate (Hz): of its grid, or of the ticks that
# filled the gaps between its samples.
int64 end_ns
float64 rate_hz
"""
WORLD_MSG = """\
# The world the producers saw at header.stamp (the tick): every entity present, in row order.
std_msgs/Header header
string[] ids
# Perception time (ns) of each entity; -9223372036854775808: not perceived yet.
int64[] perceived_ns
# x, y, z (m), roll, pitch, yaw (rad): 6 numbers per entity.
float64[] poses
# A joint's pose relative to its agent, 6 numbers per entity (zeros for the others).
float64[] local_poses
# Box size x, y, z (m), 3 per entity; NaN: the kind's default.
float64[] sizes
# The hand joint holding the entity, else "".
string[] held_by
# Shape role (support, container, none) or "".
string[] roles
# Lid: 1 closed, 0 open, -1 never said.
int8[] closed
"""


def recorded_types() -> dict[str, Any]:
    """The Run and World messages as rosbags types."""
    from rosbags.typesys import get_types_from_msg

    return get_types_from_msg(RUN_MSG, RUN_TYPE) | get_types_from_msg(WORLD_MSG, WORLD_TYPE)


@dataclass(frozen=True)
class RunInfo:
    """How a run was set up: what ``/toaster/run`` holds."""

    start_ns: int
    end_ns: int
    self_id: str
    holders: str | tuple[str, ...]
    config: dict[str, Any]
    areas: dict[str, dict[str, Any]]
    entities: list[tuple[str, str, str, str, str]]  # (id, kind, name, owner, mobility)
    settings: dict[str, Any] = field(default_factory=dict)
    agent_views: bool = True
    rate_hz: float = 0.0

    @property
    def kinds(self) -> dict[str, str]:
        """Kind by entity id (joints left out)."""
        return {e[0]: e[1] for e in self.entities if e[1] != "joint"}

    def fields(self) -> dict[str, Any]:
        """The Run message's fields."""
        ids, kinds, names, owners, mobility = (list(c) for c in zip(*self.entities, strict=True))
        holders = self.holders if isinstance(self.holders, str) else json.dumps(self.holders)
        return {
            "header": {"stamp": self.start_ns, "frame_id": "map"},
            "self_id": self.self_id,
            "holders_json": holders,
            "config_json": json.dumps(self.config, sort_keys=True),
            "areas_json": json.dumps(self.areas, sort_keys=True),
            "settings_json": json.dumps(self.settings, sort_keys=True),
            "ids": ids,
            "kinds": kinds,
            "names": names,
            "owners": owners,
            "mobility": mobility,
            "agent_views": self.agent_views,
            "end_ns": self.end_ns,
            "rate_hz": self.rate_hz,
        }

    @classmethod
    def from_msg(cls, msg: Any, start_ns: int) -> RunInfo:
        """A RunInfo from a decoded Run message (logged at ``start_ns``); ValueError (one
        line) for one whose fields do not parse."""
        from toaster.world.areaspec import normalize_area

        holders = str(msg.holders_json)
        areas = json.loads(msg.areas_json)
        if not isinstance(areas, dict) or not (holders in ("humans", "none") or holders[:1] == "["):
            text = "areas_json is not a mapping of specs, or holders_json not humans|none|[ids]"
            raise ValueError(text)
        try:  # checked, and kept as the run stored them (a scenario's specs as written)
            for area_id, spec in areas.items():
                normalize_area(str(area_id), spec)
        except InvalidInputError as exc:
            raise ValueError(str(exc)) from None
        return cls(
            start_ns,
            int(msg.end_ns),
            str(msg.self_id),
            holders if holders in ("humans", "none") else tuple(json.loads(holders)),
            json.loads(msg.config_json),
            areas,
            [
                tuple(map(str, row))  # type: ignore[misc]
                for row in zip(msg.ids, msg.kinds, msg.names, msg.owners, msg.mobility, strict=True)
            ],
            json.loads(msg.settings_json),
            bool(msg.agent_views),
            float(msg.rate_hz),
        )


def world_entities(world: World) -> list[tuple[str, str, str, str, str]]:
    """Every row of ``world`` as ``(id, kind, name, owner, mobility)``, in row order."""
    ids = world.ids
    return [
        (
            ids[r],
            world.kind_text[r],
            world.joint_names[r] if world.kind[r] == JOINT else world.names[r],
            ids[int(world.owner[r])] if world.owner[r] >= 0 else "",
            world.mobility[r],
        )
        for r in range(world.n)
    ]


def world_fields(world: World, t_ns: int) -> dict[str, Any]:
    """The World message of ``world`` at ``t_ns``: every present row, as the run holds it."""
    rows = np.flatnonzero(world.active[: world.n])
    ids = [world.ids[r] for r in rows.tolist()]
    held = world.held_by[rows]
    return {
        "header": {"stamp": t_ns, "frame_id": "map"},
        "ids": ids,
        "perceived_ns": world.t_ns[rows].copy(),
        "poses": np.hstack([world.pos[rows], world.rpy[rows]]).reshape(-1),
        "local_poses": np.hstack([world.local_pos[rows], world.local_rpy[rows]]).reshape(-1),
        "sizes": world.size[rows].reshape(-1),
        "held_by": [world.ids[h] if h >= 0 else "" for h in held.tolist()],
        "roles": [world.roles.get(i, "") for i in ids],
        "closed": np.array([_lid(world.closed.get(i)) for i in ids], np.int8),
    }


def _lid(closed: bool | None) -> int:
    return -1 if closed is None else int(closed)


class WorldReplay:
    """A source that sets the world to each recorded World message at its stamp: the same
    rows, poses, perception times, sizes, roles, lids and held objects the run had."""

    def __init__(self, name: str, info: RunInfo, states: Sequence[tuple[int, Any]]) -> None:
        self.name, self.info = name, info
        ordered = sorted(states, key=lambda item: item[0])
        check_recorded(info, ordered)
        self.times = np.array([t for t, _ in ordered], np.int64)
        self.states = [msg for _, msg in ordered]
        self._next = 0
        # what a bag source tells a run (as :class:`toaster.world.bags.BagSource`)
        self.areas = dict(info.areas)
        self.kinds = info.kinds
        self.start_ns = info.start_ns
        self.end_ns = int(self.times[-1]) if len(self.times) else info.start_ns
        self.sample_hz = info.rate_hz or None
        self.problems: Counter[str] = Counter()

    def sample_times(self) -> np.ndarray:
        """The run's ticks: the times of the recorded states."""
        return self.times

    def setup(self, world: World) -> None:
        """Add the run's entities in its row order, none present until the first state."""
        for entity_id, kind, name, owner, mobility in self.info.entities:
            world.add_entity(entity_id, kind, owner_id=owner, name=name, mobility=mobility)
        world.active[: world.n] = False

    def advance(self, world: World, t_ns: int) -> None:
        """Apply the newest state stamped at or before ``t_ns`` (once)."""
        end = int(np.searchsorted(self.times, t_ns, side="right"))
        if end > self._next:
            self._next = end
            apply_state(world, self.states[end - 1])


def check_recorded(info: RunInfo, states: Sequence[tuple[int, Any]]) -> None:
    """Refuse (ValueError, one line) a recorded run whose entities or states do not fit
    together, before anything is replayed."""
    known: set[str] = set()
    for entity_id, kind, _, owner, _ in info.entities:
        if entity_id in known or kind not in KIND_CODES:
            msg = f"entity {entity_id!r} of kind {kind!r} is declared twice or of no known kind"
            raise ValueError(msg)
        if kind == "joint" and owner not in known:
            msg = f"joint {entity_id!r} comes before its agent {owner!r}"
            raise ValueError(msg)
        known.add(entity_id)
    if not states:
        msg = "no world state"
        raise ValueError(msg)
    for t_ns, state in states:
        n = len(state.ids)
        sizes = {
            "perceived_ns": (len(state.perceived_ns), n),
            "poses": (len(state.poses), 6 * n),
            "local_poses": (len(state.local_poses), 6 * n),
            "sizes": (len(state.sizes), 3 * n),
            "held_by": (len(state.held_by), n),
            "roles": (len(state.roles), n),
            "closed": (len(state.closed), n),
        }
        wrong = [f"{k} has {got}, not {want}" for k, (got, want) in sizes.items() if got != want]
        unknown = (set(state.ids) | set(state.held_by)) - known - {""}
        if wrong or unknown or len(set(state.ids)) < n:
            what = "; ".join(wrong) or f"unknown or repeated entities {sorted(unknown)[:3]}"
            msg = f"the world state at {t_ns} ns does not fit: {what}"
            raise ValueError(msg)
        if not (np.isfinite(state.poses).all() and np.isfinite(state.local_poses).all()):
            msg = f"the world state at {t_ns} ns holds a non-finite pose"
            raise ValueError(msg)


def apply_state(world: World, msg: Any) -> None:
    """Set ``world`` to a World message (``msg``: its decoded fields)."""
    rows = world.rows_of(msg.ids)  # (checked by check_recorded: every id is known)
    present = np.zeros(world.n, bool)
    present[rows] = True
    for gone in np.flatnonzero(world.active[: world.n] & ~present).tolist():
        if world.active[gone]:  # (an agent's leaving takes its joints along)
            world.remove_entity(world.ids[gone])
    poses = np.asarray(msg.poses, float).reshape(-1, 6)
    local = np.asarray(msg.local_poses, float).reshape(-1, 6)
    world.active[rows] = True
    world.t_ns[rows] = np.asarray(msg.perceived_ns, np.int64)
    world.pos[rows], world.rpy[rows] = poses[:, :3], poses[:, 3:]
    world.local_pos[rows], world.local_rpy[rows] = local[:, :3], local[:, 3:]
    world.size[rows] = np.asarray(msg.sizes, float).reshape(-1, 3)
    world.held_by[rows] = [world.index[h] if h else -1 for h in msg.held_by]
    for entity_id, role, lid in zip(
        msg.ids, msg.roles, np.asarray(msg.closed).tolist(), strict=True
    ):
        if role:
            world.roles[entity_id] = role
        if lid >= 0:
            world.closed[entity_id] = bool(lid)
