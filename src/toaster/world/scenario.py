"""Scenario files (YAML or JSON), the toaster_simu replacement: entities, areas and a timeline.

See docs/producers.md for the format. The simulator is deterministic: the pose of a moving
entity at time t is computed from its waypoints, so replays give identical worlds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toaster.documents import read_document
from toaster.errors import FileFormatError, InvalidInputError
from toaster.timeutil import parse_duration, parse_time
from toaster.world.geometry import wrap_angle
from toaster.world.state import World

ACTIONS = ("set_pose", "move", "put_in_hand", "remove_from_hand", "enter", "leave", "look_at",
           "stop_looking", "point", "stop_pointing", "open", "close")
ARM_LENGTH = 0.6


def _vec(value: Any, where: str, size: int = 3) -> list[float]:
    if not isinstance(value, list | tuple) or not 2 <= len(value) <= size:
        msg = f"{where}: {value!r} is not a position; write [x, y] or [x, y, z] in metres"
        raise FileFormatError(msg)
    try:
        out = [float(v) for v in value]
    except (TypeError, ValueError):
        msg = f"{where}: {value!r} holds a non-number; positions are plain metres"
        raise FileFormatError(msg) from None
    if not all(math.isfinite(v) for v in out):
        msg = f"{where}: {value!r} is not finite"
        raise FileFormatError(msg)
    return out + [0.0] * (size - len(out))


def _rpy(item: Mapping[str, Any], where: str) -> list[float]:
    """Orientation of a pose: ``rpy``, ``orientation`` (a quaternion x, y, z, w, as ROS gives
    it) or ``yaw`` (radians)."""
    if "rpy" in item:
        return _vec(item["rpy"], f"{where} rpy")
    if "orientation" in item:
        from toaster.world.live import quaternion_to_rpy

        q = item["orientation"]
        if (not isinstance(q, list | tuple) or len(q) != 4
                or not all(isinstance(v, int | float) and not isinstance(v, bool)
                           and math.isfinite(v) for v in q)):
            msg = f"{where}: orientation {q!r} must be a quaternion [x, y, z, w] of numbers"
            raise FileFormatError(msg)
        try:
            return list(quaternion_to_rpy(*map(float, q)))
        except ValueError as exc:
            msg = f"{where}: {exc}"
            raise FileFormatError(msg) from None
    yaw = item.get("yaw", 0.0)
    if isinstance(yaw, bool) or not isinstance(yaw, int | float):
        msg = f"{where}: yaw {yaw!r} must be a number in radians"
        raise FileFormatError(msg)
    return [0.0, 0.0, float(yaw)]


@dataclass
class _Motion:
    start_ns: int
    points: np.ndarray  # (k, 3), first = start position
    cum: np.ndarray  # cumulative length at each point
    speed: float


@dataclass
class Scenario:
    """A parsed scenario: what to add, the areas, the thresholds and the sorted timeline."""

    name: str
    start_ns: int
    end_ns: int
    rate_hz: float
    self_id: str
    entities: list[dict[str, Any]]
    areas: dict[str, dict[str, Any]]
    config: dict[str, Any]
    timeline: list[dict[str, Any]] = field(default_factory=list)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file (.yaml, .yml or .json)."""
    path = Path(path)
    return parse_scenario(read_document(path, "scenario"), path.name)


def parse_scenario(data: Any, origin: str = "scenario") -> Scenario:
    """Validate a scenario already loaded as a dict."""
    if not isinstance(data, dict) or not isinstance(data.get("entities"), list):
        msg = f"{origin}: a scenario is a mapping with an 'entities' list"
        raise FileFormatError(msg)
    try:
        start = parse_time(data.get("start", 0))
        duration = parse_duration(str(data.get("duration", "10s")))
    except InvalidInputError as exc:
        msg_0 = f"{origin}: {exc}"
        raise FileFormatError(msg_0) from None
    rate = data.get("rate", 30)
    if isinstance(rate, bool) or not isinstance(rate, int | float) or rate <= 0:
        msg = f"{origin}: rate {rate!r} must be a positive number of ticks per second"
        raise FileFormatError(msg)
    known: dict[str, str] = {}
    for i, ent in enumerate(data["entities"]):
        where = f"{origin}: entities[{i}]"
        if not isinstance(ent, dict) or not isinstance(ent.get("id"), str) or not ent["id"]:
            msg = f"{where} needs a text 'id'"
            raise FileFormatError(msg)
        kind = str(ent.get("kind", "object")).lower()
        if kind not in ("human", "robot", "object"):
            msg = f"{where} ({ent['id']}): kind {kind!r} must be human, robot or object"
            raise FileFormatError(msg)
        known[ent["id"]] = kind
        _vec(ent.get("position", [0, 0, 0]), f"{where} position")
        _rpy(ent, where)
        for j in ent.get("joints", []) or []:
            if kind == "object" or not isinstance(j, dict) or "name" not in j:
                msg = f"{where}: joints belong to humans or robots and need a 'name'"
                raise FileFormatError(msg)
            known[j.get("id", f"{ent['id']}/{j['name']}")] = "joint"
    self_id = str(data.get("self", "") or next(
        (e["id"] for e in data["entities"] if e.get("self")), ""))
    if self_id and known.get(self_id) != "robot":
        msg = f"{origin}: self {self_id!r} is not a robot of the scenario"
        raise FileFormatError(msg)
    timeline = []
    for i, action in enumerate(data.get("timeline", []) or []):
        timeline.append(_check_action(action, i, known, origin))
    timeline.sort(key=lambda a: a["at_ns"])  # stable: file order within one time
    areas = data.get("areas", {}) or {}
    if not isinstance(areas, dict):
        msg = f"{origin}: 'areas' must map area names to specs"
        raise FileFormatError(msg)
    config = data.get("config", {}) or {}
    if "monitor" in data:
        config = {**config, "monitored_agents": data["monitor"]}
    return Scenario(str(data.get("name", origin)), start, start + duration, float(rate),
                    self_id, data["entities"], areas, config, timeline)


def _check_action(action: Any, i: int, known: dict[str, str], origin: str) -> dict[str, Any]:
    where = f"{origin}: timeline[{i}]"
    if not isinstance(action, dict):
        msg = f"{where} must be a mapping such as {{at: 1s, set_pose: Bob, position: [1, 2]}}"
        raise FileFormatError(msg)
    verbs = [k for k in action if k in ACTIONS]
    if len(verbs) != 1:
        msg = f"{where}: give exactly one action among {', '.join(ACTIONS)}"
        raise FileFormatError(msg)
    verb = verbs[0]
    subject = action[verb]
    if subject not in known:
        msg = f"{where}: {verb} names unknown entity {subject!r}; declare it under 'entities'"
        raise FileFormatError(msg)
    try:
        at = parse_duration(str(action.get("at", "0s")))
    except InvalidInputError as exc:
        msg_0 = f"{where}: {exc}"
        raise FileFormatError(msg_0) from None
    for key in ("target", "agent"):
        if key in action and action[key] not in known:
            msg = f"{where}: {key} {action[key]!r} is unknown; declare it under 'entities'"
            raise FileFormatError(msg)
    if verb == "move":
        pts = action.get("waypoints")
        if not isinstance(pts, list) or not pts:
            msg = f"{where}: move needs 'waypoints', a list of [x, y] or [x, y, z]"
            raise FileFormatError(msg)
        for p in pts:
            _vec(p, f"{where} waypoint")
        speed = action.get("speed", 1.0)
        if isinstance(speed, bool) or not isinstance(speed, int | float) or speed <= 0:
            msg = f"{where}: speed {speed!r} must be a positive number of m/s"
            raise FileFormatError(msg)
    if verb in ("set_pose", "enter") and "position" in action:
        _vec(action["position"], f"{where} position")
    if verb == "put_in_hand" and ("agent" not in action or "hand" not in action):
        msg = f"{where}: put_in_hand needs 'agent' and 'hand' (a joint name)"
        raise FileFormatError(msg)
    if verb in ("look_at", "point") and "target" not in action:
        msg = f"{where}: {verb} needs a 'target' entity"
        raise FileFormatError(msg)
    return {**action, "verb": verb, "subject": subject, "at_ns": at}


class ScenarioSource:
    """Plays a scenario into a world (humans and robots are re-perceived every tick)."""

    def __init__(self, scenario: Scenario, name: str = "simu") -> None:
        self.scenario = scenario
        self.name = name
        self._next = 0
        self._motions: dict[str, _Motion] = {}
        self._looking: dict[str, str] = {}
        self._pointing: dict[str, tuple[str, str, list[float], list[float]]] = {}
        self._present: set[str] = set()
        self._dirty: set[str] = set()
        self._kind: dict[str, str] = {}
        self._pose: dict[str, tuple[list[float], list[float]]] = {}

    @property
    def start_ns(self) -> int:
        """First tick time."""
        return self.scenario.start_ns

    @property
    def end_ns(self) -> int:
        """Last tick time."""
        return self.scenario.end_ns

    def setup(self, world: World) -> None:
        """Add the scenario's entities and joints to the world."""
        for ent in self.scenario.entities:
            eid, kind = ent["id"], str(ent.get("kind", "object")).lower()
            world.add_entity(eid, kind, name=ent.get("name", ""), size=ent.get("size"),
                             mobility=ent.get("mobility", "full"))
            self._kind[eid] = kind
            if "role" in ent or "closed" in ent:
                world.set_shape(eid, role=ent.get("role"), closed=ent.get("closed"))
            self._pose[eid] = (_vec(ent.get("position", [0, 0, 0]), eid), _rpy(ent, eid))
            for j in ent.get("joints", []) or []:
                jid = j.get("id", f"{eid}/{j['name']}")
                world.add_entity(jid, "joint", owner_id=eid, name=j["name"])
                world.set_joint_local(jid, _vec(j.get("position", [0, 0, 0]), jid), _rpy(j, jid))
            if ent.get("present", True):
                self._present.add(eid)
                self._dirty.add(eid)
            else:
                world.remove_entity(eid)

    def advance(self, world: World, t_ns: int) -> None:
        """Apply the timeline up to ``t_ns`` and report the poses at ``t_ns``."""
        timeline, start = self.scenario.timeline, self.scenario.start_ns
        while self._next < len(timeline) and start + timeline[self._next]["at_ns"] <= t_ns:
            self._apply(world, timeline[self._next], start + timeline[self._next]["at_ns"])
            self._next += 1
        for eid, motion in list(self._motions.items()):
            self._pose[eid] = (self._along(motion, t_ns, eid), self._pose[eid][1])
            self._dirty.add(eid)
            if (t_ns - motion.start_ns) / 1e9 * motion.speed >= motion.cum[-1]:
                del self._motions[eid]
        report = sorted(e for e in self._present
                        if self._kind[e] in ("human", "robot") or e in self._dirty)
        self._dirty.clear()
        if report:
            pos = np.array([self._pose[e][0] for e in report])
            rpy = np.array([self._pose[e][1] for e in report])
            world.observe(self.name, report, np.full(len(report), t_ns), pos, rpy)
        self._update_joints(world, t_ns)

    def _along(self, motion: _Motion, t_ns: int, eid: str) -> list[float]:
        travelled = max(0.0, (t_ns - motion.start_ns) / 1e9 * motion.speed)
        k = int(np.searchsorted(motion.cum, travelled, side="right"))
        if k >= len(motion.cum):
            pos = motion.points[-1]
            k = len(motion.cum) - 1
        else:
            seg = motion.cum[k] - motion.cum[k - 1]
            f = (travelled - motion.cum[k - 1]) / seg if seg else 1.0
            pos = motion.points[k - 1] + f * (motion.points[k] - motion.points[k - 1])
        d = motion.points[k] - motion.points[k - 1]
        if np.hypot(d[0], d[1]) > 0:
            rpy = self._pose[eid][1]
            self._pose[eid] = (self._pose[eid][0], [rpy[0], rpy[1], math.atan2(d[1], d[0])])
        return [float(v) for v in pos]

    def _apply(self, world: World, action: dict[str, Any], at_ns: int) -> None:
        verb, eid = action["verb"], action["subject"]
        pos, rpy = self._pose.get(eid, ([0.0] * 3, [0.0] * 3))
        if verb in ("set_pose", "enter"):
            self._motions.pop(eid, None)
            if "position" in action:
                pos = _vec(action["position"], eid)
            if "yaw" in action or "rpy" in action:
                rpy = _rpy(action, eid)
            self._pose[eid] = (pos, rpy)
            self._dirty.add(eid)
            if verb == "enter":
                world.add_entity(eid, self._kind[eid])
                for member in np.flatnonzero(world.owner[: world.n] == world.row(eid)):
                    world.active[member] = True
                self._present.add(eid)
        elif verb == "leave":
            self._present.discard(eid)
            self._motions.pop(eid, None)
            world.remove_entity(eid)
        elif verb == "move":
            pts = np.array([pos] + [_vec(p, eid) for p in action["waypoints"]])
            pts[1:, 2] = np.where([len(p) < 3 for p in action["waypoints"]], pos[2], pts[1:, 2])
            cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
            self._motions[eid] = _Motion(at_ns, pts, cum, float(action.get("speed", 1.0)))
        elif verb == "put_in_hand":
            world.put_in_hand(eid, action["agent"], action["hand"])
        elif verb == "remove_from_hand":
            world.remove_from_hand(eid)
            row = world.row(eid)
            self._pose[eid] = (world.pos[row].tolist(), world.rpy[row].tolist())
        elif verb == "look_at":
            self._looking[eid] = action["target"]
        elif verb == "stop_looking":
            self._looking.pop(eid, None)
        elif verb == "point":
            hand = action.get("hand", "rightHand")
            jrow = world.joint_of(eid, hand)
            if jrow < 0:
                msg = f"point: agent {eid!r} has no joint {hand!r}; declare it under its joints"
                raise FileFormatError(msg)
            self._pointing[eid] = (action["target"], world.ids[jrow],
                                   world.local_pos[jrow].tolist(), world.local_rpy[jrow].tolist())
        elif verb in ("open", "close"):
            world.closed[eid] = verb == "close"
        elif verb == "stop_pointing" and eid in self._pointing:
            _, jid, lpos, lrpy = self._pointing.pop(eid)
            world.set_joint_local(jid, lpos, lrpy)

    def _update_joints(self, world: World, t_ns: int) -> None:
        for agent, target in self._looking.items():
            head = world.joint_of(agent, "head")
            if head < 0 or agent not in self._present:
                continue
            a, tg = world.row(agent), world.row(target)
            head_world = world.pos[a] + _rot_yaw(world.rpy[a, 2]) @ world.local_pos[head]
            d = world.pos[tg] - head_world
            yaw = math.atan2(d[1], d[0])
            pitch = -math.atan2(d[2], math.hypot(d[0], d[1]))
            world.set_joint_local(world.ids[head], world.local_pos[head],
                                  [0.0, pitch, wrap_angle(yaw - world.rpy[a, 2])], t_ns)
        for agent, (target, jid, lpos, _) in self._pointing.items():
            a, tg = world.row(agent), world.row(target)
            d = world.pos[tg, :2] - world.pos[a, :2]
            yaw = wrap_angle(math.atan2(d[1], d[0]) - world.rpy[a, 2])
            local = [ARM_LENGTH * math.cos(yaw), ARM_LENGTH * math.sin(yaw), lpos[2]]
            world.set_joint_local(jid, local, [0.0, 0.0, yaw], t_ns)


def _rot_yaw(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
