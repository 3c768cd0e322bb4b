"""toaster's world and facts as Foxglove channels (the ``foxglove`` extra, ``foxglove-sdk``): one
mapping shared by the live server (:mod:`toaster.foxglove`) and Foxglove recordings
(:mod:`toaster.outputs.foxglove.record`), so that a recording opens as the live view did.

Channels (:data:`TOPICS`; docs/foxglove.md):

* ``/toaster/scene``, ``/toaster/areas``, ``/toaster/motion`` (``foxglove.SceneUpdate``):
  entities with their shapes, areas (owner-relative ones where their owner is now), motion and
  gaze, drawn from what :mod:`toaster.outputs.markers` computes for RViz;
* ``/tf`` (``foxglove.FrameTransforms``): every entity's frame under ``map``;
* ``/toaster/facts`` (JSON): the self agent's facts, one message per producer and tick;
* ``/toaster/beliefs`` (JSON): what each holder believes, one message per holder, each fact
  marked ``false_belief`` when the self agent does not hold it with that value;
* ``/toaster/events`` (JSON) and ``/toaster/log`` (``foxglove.Log``): belief changes;
* ``/toaster/health`` (JSON): ticks, tick time, overruns, dropped messages, the status line.

Every call takes a ``foxglove.Context`` (:class:`Channels`), so a server and a recording in one
process never mix their messages.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from toaster.model import EventRow, Fact, FactRow
from toaster.outputs import markers
from toaster.world.state import World
from toaster.world.tftree import strip_frame

SCENE_TOPIC, AREAS_TOPIC, MOTION_TOPIC = "/toaster/scene", "/toaster/areas", "/toaster/motion"
TF_TOPIC, LOG_TOPIC = "/tf", "/toaster/log"
FACTS_TOPIC, BELIEFS_TOPIC = "/toaster/facts", "/toaster/beliefs"
EVENTS_TOPIC, HEALTH_TOPIC = "/toaster/events", "/toaster/health"

_TIME = {
    "type": "object",
    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
    "required": ["sec", "nsec"],
}
_FACT = {
    "type": "object",
    "properties": {
        "subject": {"type": "string"},
        "property": {"type": "string"},
        "target": {"type": "string"},
        "value": {"type": "string"},
        "value_num": {"type": ["number", "null"]},
        "confidence": {"type": "number"},
        "since": _TIME,
        "false_belief": {"type": "boolean"},
        "self_value": {"type": ["string", "null"]},
    },
    "required": ["subject", "property", "target", "value", "confidence", "since"],
}


def _schema(title: str, props: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "title": title,
        "type": "object",
        "properties": {"timestamp": _TIME, **props},
        "required": ["timestamp", *props],
    }


_S, _I, _N = {"type": "string"}, {"type": "integer"}, {"type": "number"}
#: the JSON channels' schemas (JSON Schema, draft 2020-12 subset Foxglove reads)
JSON_SCHEMAS: dict[str, dict[str, Any]] = {
    FACTS_TOPIC: _schema(
        "toaster.Facts",
        {"agent": _S, "producer": _S, "facts": {"type": "array", "items": _FACT}},
    ),
    BELIEFS_TOPIC: _schema(
        "toaster.Beliefs",
        {
            "holder": _S,
            "chain": {"type": "array", "items": _S},
            "is_self": {"type": "boolean"},
            "false_beliefs": _I,
            "facts": {"type": "array", "items": _FACT},
        },
    ),
    EVENTS_TOPIC: _schema(
        "toaster.Event",
        {
            "agent": _S,
            "kind": _S,
            "subject": _S,
            "property": _S,
            "target": _S,
            "value": {"type": ["string", "null"]},
            "previous": {"type": ["string", "null"]},
            "confidence": {"type": ["number", "null"]},
            "line": _S,
        },
    ),
    HEALTH_TOPIC: _schema(
        "toaster.Health",
        {
            "ticks": _I,
            "tick_ms": _N,
            "worst_ms": _N,
            "overruns": _I,
            "dropped": _I,
            "warnings": _I,
            "status": _S,
        },
    ),
}
#: every channel: topic -> schema name
TOPICS = {
    SCENE_TOPIC: "foxglove.SceneUpdate",
    AREAS_TOPIC: "foxglove.SceneUpdate",
    MOTION_TOPIC: "foxglove.SceneUpdate",
    TF_TOPIC: "foxglove.FrameTransforms",
    LOG_TOPIC: "foxglove.Log",
    **{topic: schema["title"] for topic, schema in JSON_SCHEMAS.items()},
}


def timestamp(t_ns: int) -> dict[str, int]:
    """Foxglove's JSON time."""
    return {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000}


def fact_item(fact: Fact | FactRow, since_ns: int, false_belief: bool = False) -> dict[str, Any]:
    """One fact as the JSON channels carry it."""
    return {
        "subject": fact.subject_id,
        "property": fact.property,
        "target": fact.target_id,
        "value": fact.value_text,
        "value_num": fact.value_num,
        "confidence": float(fact.confidence),
        "since": timestamp(getattr(fact, "valid_from_ns", since_ns)),
        "false_belief": false_belief,
    }


def _key(fact: Fact | FactRow) -> tuple[str, ...]:
    """A belief's key, as :func:`toaster.beliefs.false_beliefs` compares holders."""
    return (
        fact.subject_id,
        fact.subject_owner_id,
        fact.property,
        fact.sub_property,
        fact.target_id,
        fact.target_owner_id,
    )


def beliefs_message(
    t_ns: int,
    holder: str,
    facts: Iterable[Fact | FactRow],
    truth: Iterable[Fact | FactRow] | None,
    *,
    is_self: bool = False,
) -> dict[str, Any]:
    """``/toaster/beliefs``: what ``holder`` believes; a fact the self agent (``truth``; None:
    unknown) does not hold with the same value is a false belief (``self_value``: the self
    agent's value of that key, null if it holds none), as :func:`toaster.beliefs.
    false_beliefs` says."""
    from toaster.outputs.recording.beliefs import chain

    known = None if truth is None or is_self else {_key(f): f.value_text for f in truth}
    items = []
    for fact in facts:
        item = fact_item(fact, t_ns)
        if known is not None:
            real = known.get(_key(fact))
            item["false_belief"], item["self_value"] = real != fact.value_text, real
        items.append(item)
    return {
        "timestamp": timestamp(t_ns),
        "holder": holder,
        "chain": chain(holder),
        "is_self": is_self,
        "false_beliefs": sum(item["false_belief"] for item in items),
        "facts": items,
    }


def facts_message(
    t_ns: int, agent: str, producer: str, facts: Iterable[Fact | FactRow]
) -> dict[str, Any]:
    """``/toaster/facts``: one producer's facts of the self agent."""
    return {
        "timestamp": timestamp(t_ns),
        "agent": agent,
        "producer": producer,
        "facts": [fact_item(f, t_ns) for f in facts],
    }


def facts_json(t_ns: int, agent: str, producer: str, facts: Iterable[Fact]) -> bytes:
    """:func:`facts_message` of a tick's facts (each since ``t_ns``) as the JSON text
    ``json.dumps`` makes of it, written directly: the live node sends it every tick, and the
    dicts and their encoding took ~7 ms a tick at 100 people (docs/foxglove.md, "Latency")."""
    text: dict[str, str] = {}

    def quoted(value: str) -> str:
        got = text.get(value)
        if got is None:  # printable ASCII but quote and backslash: as json.dumps writes it
            plain = value.isascii() and value.isprintable() and '"' not in value
            got = f'"{value}"' if plain and "\\" not in value else json.dumps(value)
            text[value] = got
        return got

    def number(value: float) -> str:
        return repr(value) if math.isfinite(value) else json.dumps(value)

    stamp = json.dumps(timestamp(t_ns))
    tail = f', "since": {stamp}, "false_belief": false}}'
    items = [
        f'{{"subject": {quoted(f.subject_id)}, "property": {quoted(f.property)}, '
        f'"target": {quoted(f.target_id)}, "value": {quoted(f.value_text)}, '
        f'"value_num": {"null" if f.value_num is None else number(f.value_num)}, '
        f'"confidence": {number(float(f.confidence))}{tail}'
        for f in facts
    ]
    head = f'{{"timestamp": {stamp}, "agent": {json.dumps(agent)}, "producer": '
    return f'{head}{json.dumps(producer)}, "facts": [{", ".join(items)}]}}'.encode()


def event_message(event: EventRow) -> dict[str, Any]:
    """``/toaster/events``: one belief change."""
    from toaster.outputs.recording import event_line

    return {
        "timestamp": timestamp(event.stamp_ns),
        "agent": event.agent_id,
        "kind": event.kind,
        "subject": event.subject_id,
        "property": event.property,
        "target": event.target_id,
        "value": event.value_text,
        "previous": event.previous_text,
        "confidence": event.confidence,
        "line": event_line(event),
    }


def health_message(
    t_ns: int, stats: Any = None, dropped: int = 0, status: str = "", **counts: Any
) -> dict[str, Any]:
    """``/toaster/health`` from a node's :class:`~toaster.node.stats.LiveStats` (or the
    ``counts`` given: a recording's frames as ``ticks``)."""
    if stats is not None:
        counts = {
            "ticks": stats.ticks,
            "tick_ms": stats.tick_ms[-1] if stats.tick_ms else 0.0,
            "worst_ms": stats.worst_ms,
            "overruns": stats.overruns,
            "warnings": stats.warnings,
        }
    return {
        "timestamp": timestamp(t_ns),
        "ticks": int(counts.get("ticks", 0)),
        "tick_ms": float(counts.get("tick_ms", 0.0)),
        "worst_ms": float(counts.get("worst_ms", 0.0)),
        "overruns": int(counts.get("overruns", 0)),
        "dropped": int(dropped),
        "warnings": int(counts.get("warnings", 0)),
        "status": status,
    }


# -- the scene: RViz marker dicts (markers.py) as SceneUpdates ---------------------------------
def _fg() -> Any:
    from foxglove import messages

    return messages


def _vec(m: Any, d: Mapping[str, float]) -> Any:
    return m.Vector3(x=float(d["x"]), y=float(d["y"]), z=float(d["z"]))


def _pose(m: Any, pose: Mapping[str, Any]) -> Any:
    q = pose["orientation"]
    return m.Pose(
        position=_vec(m, pose["position"]),
        orientation=m.Quaternion(x=q["x"], y=q["y"], z=q["z"], w=q["w"]),
    )


def _towards(m: Any, a: Sequence[float], b: Sequence[float]) -> tuple[Any, float]:
    """The pose at ``a`` whose x axis points to ``b``, and the distance."""
    dx, dy, dz = (b[i] - a[i] for i in range(3))
    yaw, pitch = math.atan2(dy, dx), -math.atan2(dz, math.hypot(dx, dy))
    cy, sy, cp, sp = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(pitch / 2), math.sin(pitch / 2)
    q = m.Quaternion(x=-sp * sy, y=sp * cy, z=cp * sy, w=cp * cy)
    point = m.Vector3(x=float(a[0]), y=float(a[1]), z=float(a[2]))
    return m.Pose(position=point, orientation=q), math.dist(a, b)


def _color(m: Any, c: Mapping[str, float]) -> Any:
    return m.Color(r=c["r"], g=c["g"], b=c["b"], a=c["a"])


def _primitive(m: Any, mk: Mapping[str, Any], kinds: dict[str, list[Any]]) -> None:
    """Add one RViz marker's Foxglove primitive to ``kinds`` (cubes, arrows...)."""
    kind, scale, color = mk["type"], mk["scale"], _color(m, mk["color"])
    points = [(p["x"], p["y"], p["z"]) for p in mk["points"]]
    if kind in (markers.CUBE, markers.CYLINDER, markers.SPHERE):
        name = {markers.CUBE: "cubes", markers.CYLINDER: "cylinders"}.get(kind, "spheres")
        extra = {"bottom_scale": 1.0, "top_scale": 1.0} if kind == markers.CYLINDER else {}
        cls = {"cubes": m.CubePrimitive, "cylinders": m.CylinderPrimitive}.get(
            name, m.SpherePrimitive
        )
        kinds[name].append(
            cls(pose=_pose(m, mk["pose"]), size=_vec(m, scale), color=color, **extra)
        )
    elif kind == markers.SPHERE_LIST:
        for p in points:
            where = {"position": dict(zip("xyz", p, strict=True)), "orientation": _UNIT}
            kinds["spheres"].append(
                m.SpherePrimitive(pose=_pose(m, where), size=_vec(m, scale), color=color)
            )
    elif kind == markers.ARROW:
        if len(points) >= 2:
            pose, length = _towards(m, points[0], points[1])
            shaft, head = scale["x"], scale["y"]
        else:
            pose, length = _pose(m, mk["pose"]), scale["x"]
            shaft, head = scale["y"], 2 * scale["y"]
        kinds["arrows"].append(
            m.ArrowPrimitive(
                pose=pose,
                shaft_length=0.77 * length,
                shaft_diameter=shaft,
                head_length=0.23 * length,
                head_diameter=head,
                color=color,
            )
        )
    elif kind in (markers.LINE_STRIP, markers.LINE_LIST):
        line = m.LinePrimitiveLineType
        kinds["lines"].append(
            m.LinePrimitive(
                type=line.LineStrip if kind == markers.LINE_STRIP else line.LineList,
                thickness=scale["x"],
                points=[m.Point3(x=p[0], y=p[1], z=p[2]) for p in points],
                color=color,
            )
        )
    elif kind == markers.TEXT:
        kinds["texts"].append(
            m.TextPrimitive(
                pose=_pose(m, mk["pose"]),
                billboard=True,
                font_size=scale["z"],
                color=color,
                text=mk["text"],
            )
        )


_UNIT = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
_KINDS = ("cubes", "cylinders", "spheres", "arrows", "lines", "texts")


def scene_update(t_ns: int, drawn: Iterable[Mapping[str, Any]], frame_id: str = "map") -> Any:
    """A SceneUpdate of RViz marker dicts: everything older deleted (their DELETEALL), one
    entity per marker namespace (an entity id, an area, a fact's property)."""
    m = _fg()
    stamp = m.Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)
    grouped: dict[str, dict[str, list[Any]]] = {}
    for mk in drawn:
        if mk["action"] == markers.DELETEALL:
            continue
        _primitive(m, mk, grouped.setdefault(mk["ns"], {k: [] for k in _KINDS}))
    entities = [
        m.SceneEntity(timestamp=stamp, frame_id=frame_id, id=ns, **kinds)
        for ns, kinds in grouped.items()
    ]
    deletion = m.SceneEntityDeletion(timestamp=stamp, type=m.SceneEntityDeletionType.All)
    return m.SceneUpdate(deletions=[deletion], entities=entities)


def frame_transforms(t_ns: int, world: World, frame_id: str = "map") -> Any:
    """``/tf``: every live entity's frame under ``frame_id`` (pdg's names, no leading slash)."""
    m = _fg()
    stamp = m.Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)
    return m.FrameTransforms(
        transforms=[
            m.FrameTransform(
                timestamp=stamp,
                parent_frame_id=frame_id,
                child_frame_id=strip_frame(child),
                translation=m.Vector3(x=p[0], y=p[1], z=p[2]),
                rotation=m.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
            )
            for child, p, q, _ in markers.transforms(world)
        ]
    )


def occupied_areas(facts: Iterable[Fact]) -> set[str]:
    """Areas something is in, from area_manager's facts (drawn brighter)."""
    return {f.target_id for f in facts if f.property in ("IsInArea", "IsInRoom", "IsAt")}


class Channels:
    """The channels of :data:`TOPICS` in one ``foxglove.Context``, and what they publish."""

    def __init__(self, context: Any) -> None:
        import foxglove
        from foxglove import channels as fc

        self.context = context
        self.scene = fc.SceneUpdateChannel(SCENE_TOPIC, context=context)
        self.areas = fc.SceneUpdateChannel(AREAS_TOPIC, context=context)
        self.motion = fc.SceneUpdateChannel(MOTION_TOPIC, context=context)
        self.tf = fc.FrameTransformsChannel(TF_TOPIC, context=context)
        self.log = fc.LogChannel(LOG_TOPIC, context=context)
        self.json = {
            topic: foxglove.Channel(topic, schema=schema, context=context)
            for topic, schema in JSON_SCHEMAS.items()
        }

    def frame(
        self,
        t_ns: int,
        world: World,
        areas: Mapping[str, Mapping[str, Any]],
        area_facts: Sequence[Fact],
        motion_facts: Sequence[Fact],
    ) -> None:
        """The scene, the areas, motion and gaze, and /tf of ``world`` at ``t_ns`` (on the
        channels that have a sink: a client subscribed, a recording)."""
        if self.tf.has_sinks():
            self.tf.log(frame_transforms(t_ns, world), log_time=t_ns)
        if self.scene.has_sinks():
            drawn = markers.entity_markers(world, t_ns)
            entities = [mk for array in drawn.values() for mk in array]
            self.scene.log(scene_update(t_ns, entities), log_time=t_ns)
        if self.areas.has_sinks():
            area = markers.area_markers(world, areas, occupied_areas(area_facts), t_ns)
            self.areas.log(scene_update(t_ns, area), log_time=t_ns)
        if self.motion.has_sinks():
            motion = markers.motion_markers(world, motion_facts, t_ns)
            self.motion.log(scene_update(t_ns, motion), log_time=t_ns)

    def listened(self) -> bool:
        """Whether a client subscribes to any channel."""
        fixed: list[Any] = [self.scene, self.areas, self.motion, self.tf, self.log]
        return any(c.has_sinks() for c in [*fixed, *self.json.values()])

    def views_wanted(self) -> bool:
        """Whether one of the channels :meth:`frame` draws has a sink."""
        return any(c.has_sinks() for c in (self.tf, self.scene, self.areas, self.motion))

    def wanted(self, *topics: str) -> bool:
        """Whether one of the JSON ``topics`` has a sink."""
        return any(self.json[topic].has_sinks() for topic in topics)

    def put(self, topic: str, message: Mapping[str, Any]) -> None:
        """A JSON channel's message, logged at its own timestamp."""
        stamp = message["timestamp"]
        self.json[topic].log(dict(message), log_time=stamp["sec"] * 1_000_000_000 + stamp["nsec"])

    def put_json(self, topic: str, data: bytes, t_ns: int) -> None:
        """A JSON channel's message already encoded (:func:`facts_json`), logged at ``t_ns``."""
        self.json[topic].log(data, log_time=t_ns)

    def event(self, event: EventRow) -> None:
        """An event on ``/toaster/events`` and as a line on ``/toaster/log``."""
        message = event_message(event)
        self.put(EVENTS_TOPIC, message)
        m = _fg()
        t = event.stamp_ns
        self.log.log(
            m.Log(
                timestamp=m.Timestamp(sec=t // 1_000_000_000, nsec=t % 1_000_000_000),
                level=m.LogLevel.Info,
                message=message["line"],
                name=f"toaster.{event.agent_id}",
            ),
            log_time=t,
        )


__all__ = [
    "JSON_SCHEMAS",
    "TOPICS",
    "Channels",
    "beliefs_message",
    "event_message",
    "facts_json",
    "facts_message",
    "frame_transforms",
    "health_message",
    "scene_update",
]
