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

from toaster.documents import located, read_document
from toaster.errors import FileFormatError, InvalidInputError
from toaster.model import MAX_COORD, check_id, check_text, shown
from toaster.timeutil import check_ns, check_rate, parse_duration, parse_time
from toaster.world.geometry import from_frames, to_frames, wrap_angle
from toaster.world.state import MOBILITIES, World

ACTIONS = (
    "set_pose",
    "move",
    "put_in_hand",
    "remove_from_hand",
    "enter",
    "leave",
    "look_at",
    "stop_looking",
    "point",
    "stop_pointing",
    "open",
    "close",
)
ARM_LENGTH = 0.6


#: The kinds of entity a scenario declares; joints are declared under their agent.
KINDS = ("human", "robot", "object")
ROLES = ("support", "container", "none")


def _vec(value: Any, where: str, size: int = 3) -> list[float]:
    """A position ``[x, y]`` or ``[x, y, z]`` of finite metres within :data:`MAX_COORD`."""
    if not isinstance(value, list | tuple) or not 2 <= len(value) <= size:
        msg = f"{where}: {shown(value)} is not a position; write [x, y] or [x, y, z] in metres"
        raise FileFormatError(msg)
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        msg = f"{where}: {shown(value)} holds a non-number; positions are plain metres"
        raise FileFormatError(msg)
    out = [_finite(v, where, "coordinate") for v in value]
    return out + [0.0] * (size - len(out))


def _finite(value: Any, where: str, what: str, limit: float = MAX_COORD) -> float:
    """``value`` as a float if it is a number within ±``limit``, else a one-line error."""
    try:
        number = (
            float(value)
            if isinstance(value, int | float) and not isinstance(value, bool)
            else math.nan
        )
    except OverflowError:
        number = math.nan
    if not (math.isfinite(number) and abs(number) <= limit):
        msg = f"{where}: {what} {shown(value)} must be a finite number within ±{limit:g}"
        raise FileFormatError(msg)
    return number


def _rpy(item: Mapping[str, Any], where: str) -> list[float]:
    """Orientation of a pose: ``rpy``, ``orientation`` (a quaternion x, y, z, w, as ROS gives
    it) or ``yaw`` (radians)."""
    if "rpy" in item:
        return _vec(item["rpy"], f"{where} rpy")
    if "orientation" in item:
        from toaster.world.live import quaternion_to_rpy

        q = item["orientation"]
        if (
            not isinstance(q, list | tuple)
            or len(q) != 4
            or not all(
                isinstance(v, int | float)
                and not isinstance(v, bool)
                and math.isfinite(v)
                and abs(v) <= MAX_COORD
                for v in q
            )
        ):
            msg = f"{where}: orientation {shown(q)} must be a quaternion [x, y, z, w] of numbers"
            raise FileFormatError(msg)
        try:
            return list(quaternion_to_rpy(*map(float, q)))
        except ValueError as exc:
            msg = f"{where}: {exc}"
            raise FileFormatError(msg) from None
    yaw = item.get("yaw", 0.0)
    if isinstance(yaw, bool) or not isinstance(yaw, int | float):
        msg = f"{where}: yaw {shown(yaw)} must be a number in radians"
        raise FileFormatError(msg)
    return [0.0, 0.0, _finite(yaw, where, "yaw")]


def _id(value: Any, where: str, what: str) -> str:
    """A valid id (:func:`toaster.model.check_id`) or a one-line error naming ``where``."""
    with located(where):
        return check_id(value, what)


def _flag(item: Mapping[str, Any], key: str, default: bool | None, where: str) -> bool | None:
    value = item.get(key, default)
    if value is not None and not isinstance(value, bool):
        msg = f"{where}: {key} {shown(value)} must be true or false"
        raise FileFormatError(msg)
    return value


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
    """Validate a scenario already loaded as a dict: every field, before anything runs."""
    if not isinstance(data, dict) or not isinstance(data.get("entities"), list):
        msg = f"{origin}: a scenario is a mapping with an 'entities' list"
        raise FileFormatError(msg)
    try:
        start = parse_time(data.get("start", 0))
        duration = parse_duration(str(data.get("duration", "10s")))
        check_ns(start + duration, "the scenario's end (start + duration) =")
        rate = check_rate(data.get("rate", 30))
    except InvalidInputError as exc:
        msg = f"{origin}: {exc}"
        raise FileFormatError(msg) from None
    if duration < 0:
        msg = f"{origin}: duration {data.get('duration')!r} must not be negative"
        raise FileFormatError(msg)
    entities = [_entity(ent, f"{origin}: entities[{i}]") for i, ent in enumerate(data["entities"])]
    known: dict[str, str] = {}
    joints: dict[str, tuple[str, str]] = {}  # joint id -> (agent, joint name)
    for i, ent in enumerate(entities):
        for jid in (ent["id"], *(j["id"] for j in ent["joints"])):
            if jid in known or jid in joints:
                msg = f"{origin}: entities[{i}]: id {jid!r} is declared twice; ids are unique"
                raise FileFormatError(msg)
            if jid == ent["id"]:
                known[jid] = ent["kind"]
            else:
                joints[jid] = next((ent["id"], j["name"]) for j in ent["joints"] if j["id"] == jid)
    self_id = data.get("self", "") or next((e["id"] for e in entities if e["self"]), "")
    if self_id and (not isinstance(self_id, str) or known.get(self_id) != "robot"):
        msg = f"{origin}: self {shown(self_id)} is not a robot of the scenario"
        raise FileFormatError(msg)
    raw_timeline = data.get("timeline", []) or []
    if not isinstance(raw_timeline, list):
        msg = f"{origin}: 'timeline' must be a list of actions such as {{at: 1s, leave: bob}}"
        raise FileFormatError(msg)
    timeline = [
        _check_action(action, i, known, joints, origin, start)
        for i, action in enumerate(raw_timeline)
    ]
    timeline.sort(key=lambda a: a["at_ns"])  # stable: file order within one time
    areas = data.get("areas", {}) or {}
    if not isinstance(areas, dict):
        msg = f"{origin}: 'areas' must map area names to specs"
        raise FileFormatError(msg)
    for area_id, spec in areas.items():
        check_area(area_id, spec, f"{origin}: areas")
    config = data.get("config", {}) or {}
    if not isinstance(config, dict):
        msg = f"{origin}: 'config' must map threshold names to values (docs/producers.md)"
        raise FileFormatError(msg)
    if "monitor" in data:
        config = {**config, "monitored_agents": data["monitor"]}
    from toaster.world.config import make_config

    try:
        make_config(config)
    except InvalidInputError as exc:
        msg = f"{origin}: config: {exc}"
        raise FileFormatError(msg) from None
    name = data.get("name", origin)
    if not isinstance(name, str | int | float) or isinstance(name, bool):
        msg = f"{origin}: name {shown(name)} must be text"
        raise FileFormatError(msg)
    return Scenario(
        _text(str(name), origin, "name"),
        start,
        start + duration,
        rate,
        self_id,
        entities,
        areas,
        config,
        timeline,
    )


def _text(value: Any, where: str, what: str) -> str:
    with located(where):
        return check_text(value, what)


def _entity(ent: Any, where: str) -> dict[str, Any]:
    """One entity, checked and normalised (position and rpy as 3 floats, joints checked)."""
    if not isinstance(ent, dict) or not isinstance(ent.get("id"), str) or not ent["id"]:
        msg = f"{where} needs a text 'id'"
        raise FileFormatError(msg)
    eid = _id(ent["id"], where, "entity id")
    where = f"{where} ({eid})"
    kind = ent.get("kind", "object")
    kind = kind.lower() if isinstance(kind, str) else kind
    if kind not in KINDS:
        msg = f"{where}: kind {shown(kind)} must be human, robot or object"
        raise FileFormatError(msg)
    name = ent.get("name", "")
    if name is not None and not isinstance(name, str):
        msg = f"{where}: name {shown(name)} must be text"
        raise FileFormatError(msg)
    name = _text(name or "", where, "name")
    size = ent.get("size")
    if size is not None:
        if not isinstance(size, list | tuple) or len(size) != 3:
            msg = f"{where}: size {shown(size)} must be [x, y, z], non-negative metres"
            raise FileFormatError(msg)
        size = _vec(size, f"{where} size")
        if min(size) < 0:
            msg = f"{where}: size {shown(ent['size'])} must be [x, y, z], non-negative metres"
            raise FileFormatError(msg)
    mobility = ent.get("mobility", "full")
    if mobility not in MOBILITIES:
        msg = f"{where}: mobility {shown(mobility)} must be one of {', '.join(MOBILITIES)}"
        raise FileFormatError(msg)
    role = ent.get("role")
    if role is not None and role not in ROLES:
        msg = f"{where}: role {shown(role)} must be one of {', '.join(ROLES)}"
        raise FileFormatError(msg)
    raw_joints = ent.get("joints", []) or []
    if not isinstance(raw_joints, list) or (raw_joints and kind == "object"):
        msg = f"{where}: joints are a list, and belong to humans or robots"
        raise FileFormatError(msg)
    joints = []
    for j in raw_joints:
        if not isinstance(j, dict) or "name" not in j:
            msg = f"{where}: joints belong to humans or robots and need a 'name'"
            raise FileFormatError(msg)
        jname = _id(j["name"], f"{where} joint", "joint name")
        jid = _id(j.get("id", f"{eid}/{jname}"), f"{where} joint {jname}", "joint id")
        joints.append(
            {
                "id": jid,
                "name": jname,
                "position": _vec(j.get("position", [0, 0, 0]), f"{where} joint {jname}"),
                "rpy": _rpy(j, f"{where} joint {jname}"),
            }
        )
    return {
        "id": eid,
        "kind": kind,
        "name": name,
        "size": size,
        "mobility": mobility,
        "role": role,
        "closed": _flag(ent, "closed", None, where),
        "self": _flag(ent, "self", False, where),
        "present": _flag(ent, "present", True, where),
        "position": _vec(ent.get("position", [0, 0, 0]), f"{where} position"),
        "rpy": _rpy(ent, where),
        "joints": joints,
    }


def check_area(area_id: Any, spec: Any, where: str) -> dict[str, Any]:
    """An area spec checked (:func:`toaster.world.areaspec.normalize_area`, after a check of
    its values' types), as a one-line :class:`FileFormatError` naming ``where``."""
    from toaster.world.areaspec import normalize_area

    name = _id(area_id, where, "area id")
    where = f"{where} {name}"
    if not isinstance(spec, dict):
        msg = (
            f"{where}: an area spec is a mapping such as {{shape: circle, center: [1, 2], "
            "radius: 1}"
        )
        raise FileFormatError(msg)
    for key, value in spec.items():
        if key in ("points",):
            if not isinstance(value, list) or not all(isinstance(p, list | tuple) for p in value):
                msg = f"{where}: points {shown(value)} must be a list of [x, y] corners"
                raise FileFormatError(msg)
            for p in value:
                _vec(p, f"{where} points")
        elif key == "center":
            _vec(value, f"{where} center")
        elif key in ("radius", "height", "z_min", "z_max", "enter_hysteresis", "leave_hysteresis"):
            if value is not None:
                _finite(value, where, key)
        elif key in ("facts", "entity_types"):
            if not isinstance(value, str) and not (
                isinstance(value, list) and all(isinstance(v, str) for v in value)
            ):
                msg = f"{where}: {key} {shown(value)} must be a word or a list of words"
                raise FileFormatError(msg)
        elif key in ("shape", "owner", "area_type") and value is not None:
            if not isinstance(value, str):
                msg = f"{where}: {key} {shown(value)} must be text"
                raise FileFormatError(msg)
            _text(value, where, key)
    try:
        return normalize_area(name, spec)
    except InvalidInputError as exc:
        msg = f"{where}: {exc}"
        raise FileFormatError(msg) from None


def _check_action(
    action: Any,
    i: int,
    known: dict[str, str],
    joints: dict[str, tuple[str, str]],
    origin: str,
    start: int,
) -> dict[str, Any]:
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
    if not isinstance(subject, str) or subject not in known:
        msg = f"{where}: {verb} names unknown entity {shown(subject)}; declare it under 'entities'"
        raise FileFormatError(msg)
    try:
        at = parse_duration(str(action.get("at", "0s")))
        check_ns(start + at, f"{where}: at {action.get('at')!r}: the time")
    except InvalidInputError as exc:
        msg = f"{where}: {exc}" if not str(exc).startswith(where) else str(exc)
        raise FileFormatError(msg) from None
    if at < 0:
        msg = f"{where}: at {action.get('at')!r} must not be negative (time from the start)"
        raise FileFormatError(msg)
    for key in ("target", "agent"):
        if key in action and (
            not isinstance(action[key], str)
            or (action[key] not in known and action[key] not in joints)
        ):
            msg = f"{where}: {key} {shown(action[key])} is unknown; declare it under 'entities'"
            raise FileFormatError(msg)
    out = {**action, "verb": verb, "subject": subject, "at_ns": at}
    if verb == "move":
        pts = action.get("waypoints")
        if not isinstance(pts, list) or not pts:
            msg = f"{where}: move needs 'waypoints', a list of [x, y] or [x, y, z]"
            raise FileFormatError(msg)
        out["waypoints"] = [_vec(p, f"{where} waypoint") for p in pts]
        out["flat"] = [len(p) < 3 for p in pts]
        speed = action.get("speed", 1.0)
        if (
            isinstance(speed, bool)
            or not isinstance(speed, int | float)
            or not (0 < _finite(speed, where, "speed") <= MAX_COORD)
        ):
            msg = f"{where}: speed {shown(speed)} must be a positive number of m/s"
            raise FileFormatError(msg)
        out["speed"] = float(speed)
    if verb in ("set_pose", "enter"):
        if "position" in action:
            out["position"] = _vec(action["position"], f"{where} position")
        if "yaw" in action or "rpy" in action or "orientation" in action:
            out["rpy"] = _rpy(action, where)
    if verb == "put_in_hand":
        agent, hand = action.get("agent"), action.get("hand")
        if agent is None or hand is None:
            msg = f"{where}: put_in_hand needs 'agent' and 'hand' (a joint name)"
            raise FileFormatError(msg)
        if not any(owner == agent and name == hand for owner, name in joints.values()):
            msg = (
                f"{where}: agent {shown(agent)} has no joint {shown(hand)}; declare it "
                "under the agent's joints"
            )
            raise FileFormatError(msg)
        if agent == subject:
            msg = f"{where}: {subject!r} cannot be put in its own hand"
            raise FileFormatError(msg)
    if verb in ("look_at", "point", "stop_looking", "stop_pointing") and known[subject] not in (
        "human",
        "robot",
    ):
        msg = f"{where}: {verb} is for humans and robots, not {known[subject]} {subject!r}"
        raise FileFormatError(msg)
    if verb in ("look_at", "point") and "target" not in action:
        msg = f"{where}: {verb} needs a 'target' entity"
        raise FileFormatError(msg)
    if verb == "point":
        hand = action.get("hand", "rightHand")
        if not any(owner == subject and name == hand for owner, name in joints.values()):
            msg = (
                f"{where}: point: agent {subject!r} has no joint {shown(hand)}; declare it "
                "under its joints"
            )
            raise FileFormatError(msg)
    return out


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
        """Add the scenario's entities and joints to the world (checked by the parser)."""
        for ent in self.scenario.entities:
            eid, kind = ent["id"], ent["kind"]
            world.add_entity(
                eid, kind, name=ent["name"], size=ent["size"], mobility=ent["mobility"]
            )
            self._kind[eid] = kind
            if ent["role"] is not None or ent["closed"] is not None:
                world.set_shape(eid, role=ent["role"], closed=ent["closed"])
            self._pose[eid] = (list(ent["position"]), list(ent["rpy"]))
            for j in ent["joints"]:
                world.add_entity(j["id"], "joint", owner_id=eid, name=j["name"])
                world.set_joint_local(j["id"], j["position"], j["rpy"])
            if ent["present"]:
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
        report = sorted(
            e for e in self._present if self._kind[e] in ("human", "robot") or e in self._dirty
        )
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
            pos = list(action.get("position", pos))
            rpy = list(action.get("rpy", rpy))
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
            pts = np.array([pos] + action["waypoints"])
            pts[1:, 2] = np.where(action["flat"], pos[2], pts[1:, 2])
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
            self._pointing[eid] = (
                action["target"],
                world.ids[jrow],
                world.local_pos[jrow].tolist(),
                world.local_rpy[jrow].tolist(),
            )
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
            head_world, _ = from_frames(
                world.pos[[a]], world.rpy[[a]], world.local_pos[[head]], world.local_rpy[[head]]
            )
            d = world.pos[tg] - head_world[0]
            gaze = [0.0, -math.atan2(d[2], math.hypot(d[0], d[1])), math.atan2(d[1], d[0])]
            _, head_rpy = to_frames(world.pos[[a]], world.rpy[[a]], head_world, np.array([gaze]))
            world.set_joint_local(
                world.ids[head], world.local_pos[head], head_rpy[0].tolist(), t_ns
            )
        for agent, (target, jid, lpos, _) in self._pointing.items():
            a, tg = world.row(agent), world.row(target)
            d = world.pos[tg, :2] - world.pos[a, :2]
            yaw = wrap_angle(math.atan2(d[1], d[0]) - world.rpy[a, 2])
            local = [ARM_LENGTH * math.cos(yaw), ARM_LENGTH * math.sin(yaw), lpos[2]]
            world.set_joint_local(jid, local, [0.0, 0.0, yaw], t_ns)
