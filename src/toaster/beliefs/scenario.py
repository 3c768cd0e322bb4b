"""Belief scenarios: timed facts and room changes replayed without geometry.

A scenario file (YAML or JSON)::

    name: sally-anne
    self: ROBOT                     # the self agent (a robot), registered for you
    agents: [SALLY, ANNE]           # humans
    objects: [MARBLE, BASKET, BOX, ROOM]
    settings: {depth: 2}            # optional belief settings (see toaster.beliefs.config)
    steps:
      - t: 1                        # seconds (or t_ns: integer nanoseconds)
        rooms: {SALLY: ROOM, BASKET: ROOM}   # IsInRoom; null = leaves every room
        inside: {MARBLE: BASKET}    # IsIn (replaces the entity's IsIn/IsOn); null = out
        onto: {MUG: TABLE}          # IsOn (same)
        facts: [[BOX, IsClosed], {subject: CUP, property: Contains, value: hot_water,
                                   confidence: 0.9, observability: 0.3}]
        end: [[BOX, IsClosed]]      # subject, property[, target]
        actor: ANNE                 # who made this step's changes (perceives them anywhere)
        tell: {speaker: ANNE, listeners: [SALLY], fact: [MARBLE, IsIn, BOX]}
                                    # or public: true (everyone in the speaker's room); a list
                                    # of tellings is accepted; applied after the step's changes
    expect:                         # checked by `toaster beliefs replay --check` and the tests
      - {t: 4, agent: SALLY, subject: MARBLE, property: IsIn, target: BASKET}
      - {agent: ANNE, about: SALLY, subject: MARBLE, property: IsIn, target: BOX, held: false}

Each step becomes one snapshot of the self agent (``Store.sync_snapshot``), so the belief rules
see it as one tick. Expectations are as-of queries at their ``t`` (default: the end).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toaster.beliefs import api
from toaster.beliefs.tell import tell
from toaster.documents import read_document
from toaster.errors import FileFormatError, InvalidInputError
from toaster.model import Fact, check_fact, fact_key

SOURCE = "scenario"
_FACT_FIELDS = ("subject", "property", "target", "value", "value_num", "confidence",
                "observability")


@dataclass
class Step:
    """One tick: room and container changes, facts asserted and ended."""

    t_ns: int
    rooms: dict[str, str | None] = field(default_factory=dict)
    inside: dict[str, tuple[str, str] | None] = field(default_factory=dict)
    facts: list[Fact] = field(default_factory=list)
    end: list[tuple[str, str, str | None]] = field(default_factory=list)
    actor: str | None = None
    tells: list[Telling] = field(default_factory=list)


@dataclass
class Telling:
    """A speaker tells a fact to listeners (None: everyone in its room)."""

    speaker: str
    fact: Fact
    listeners: list[str] | None


@dataclass
class Scenario:
    """A parsed scenario: entities, settings, steps and expectations."""

    name: str
    self_agent: str
    agents: list[str]
    objects: list[str]
    settings: dict[str, Any]
    steps: list[Step]
    expect: list[dict[str, Any]]


def _bad(where: str, value: object, fix: str) -> FileFormatError:
    return FileFormatError(f"{where}: invalid {value!r}: {fix}")


def _time(where: str, raw: dict[str, Any]) -> int:
    if "t_ns" in raw:
        value = raw["t_ns"]
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise _bad(where, value, "t_ns must be an integer number of nanoseconds")
    value = raw.get("t")
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return round(value * 1e9)
    raise _bad(where, value, "give t (seconds) or t_ns (integer nanoseconds) for every step")


def _fact(where: str, raw: object) -> Fact:
    if isinstance(raw, list | tuple) and 2 <= len(raw) <= 4:
        items = [str(v) for v in raw]
        raw = dict(zip(("subject", "property", "target", "value"), items, strict=False))
    if not isinstance(raw, dict) or "subject" not in raw or "property" not in raw:
        raise _bad(where, raw, "write a fact as [SUBJECT, PROPERTY, TARGET] or "
                   "{subject: S, property: P, target: T, value: V, confidence: C}")
    unknown = set(raw) - set(_FACT_FIELDS)
    if unknown:
        raise _bad(where, sorted(unknown)[0], f"fact fields are {', '.join(_FACT_FIELDS)}")
    try:
        return check_fact(Fact(str(raw["subject"]), str(raw["property"]),
                               str(raw.get("target") or ""), str(raw.get("value", "true")),
                               raw.get("value_num"), raw.get("confidence", 1.0),
                               raw.get("observability", 1.0)))
    except InvalidInputError as exc:
        msg = f"{where}: {exc}"
        raise FileFormatError(msg) from None


def _mapping(where: str, raw: object) -> dict[str, str | None]:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise _bad(where, raw, "give a mapping ENTITY: PLACE (null = none)")
    return {str(k): (None if v is None else str(v)) for k, v in raw.items()}


def _tells(where: str, raw: object) -> list[Telling]:
    items = [] if raw is None else raw if isinstance(raw, list) else [raw]
    tells = []
    for item in items:
        if (not isinstance(item, dict) or not isinstance(item.get("speaker"), str)
                or "fact" not in item or set(item) - {"speaker", "listeners", "public", "fact"}):
            raise _bad(where, item, "write a telling as {speaker: ID, listeners: [ID, ...], "
                       "fact: [SUBJECT, PROPERTY, TARGET]} (or public: true for the room)")
        listeners = item.get("listeners")
        if item.get("public"):
            listeners = None
        elif not isinstance(listeners, list) or not listeners:
            raise _bad(where, listeners, "give listeners: [ID, ...] or public: true")
        tells.append(Telling(item["speaker"], _fact(where, item["fact"]),
                             None if listeners is None else [str(v) for v in listeners]))
    return tells


def parse(data: object, name: str = "scenario") -> Scenario:
    """Validate a loaded YAML/JSON document into a :class:`Scenario`."""
    if not isinstance(data, dict) or not isinstance(data.get("steps"), list):
        raise _bad(name, type(data).__name__, "a scenario is a mapping with a list of steps")
    steps: list[Step] = []
    for i, raw in enumerate(data["steps"], 1):
        where = f"{name}: step {i}"
        if not isinstance(raw, dict):
            raise _bad(where, raw, "each step is a mapping with t and changes")
        step = Step(_time(where, raw), rooms=_mapping(where, raw.get("rooms")))
        for word, prop in (("inside", "IsIn"), ("onto", "IsOn")):
            for entity, place in _mapping(where, raw.get(word)).items():
                step.inside[entity] = None if place is None else (prop, place)
        step.facts = [_fact(where, f) for f in raw.get("facts") or []]
        for item in raw.get("end") or []:
            if not isinstance(item, list | tuple) or not 2 <= len(item) <= 3:
                raise _bad(where, item, "end a fact with [SUBJECT, PROPERTY] or "
                           "[SUBJECT, PROPERTY, TARGET]")
            step.end.append((str(item[0]), str(item[1]),
                             str(item[2]) if len(item) == 3 else None))
        actor = raw.get("actor")
        if actor is not None and not isinstance(actor, str):
            raise _bad(where, actor, "actor is the id of the agent who made the step's changes")
        step.actor = actor
        step.tells = _tells(where, raw.get("tell"))
        if steps and step.t_ns < steps[-1].t_ns:
            raise _bad(where, raw.get("t", raw.get("t_ns")), "steps must be in time order")
        steps.append(step)
    self_agent = data.get("self", "ROBOT")
    agents = data.get("agents") or []
    if not isinstance(self_agent, str) or not isinstance(agents, list):
        raise _bad(name, agents, "self is an id and agents a list of ids")
    return Scenario(str(data.get("name", name)), self_agent, [str(a) for a in agents],
                    [str(o) for o in data.get("objects") or []],
                    dict(data.get("settings") or {}), steps, list(data.get("expect") or []))


def load(path: str | Path) -> Scenario:
    """Read a scenario file (``.yaml``/``.yml`` or ``.json``)."""
    path = Path(path)
    return parse(read_document(path, "scenario"), path.name)


class Replayer:
    """Replays steps as snapshots of the self agent, keeping the world state between them."""

    def __init__(self, db: Any, scenario: Scenario) -> None:
        self.db, self.scenario = db, scenario
        self.store = db.store()
        self.state: dict[tuple[str, ...], Fact] = {}

    def setup(self) -> None:
        """Register the entities and apply the scenario's settings."""
        sc = self.scenario
        if sc.settings:
            api.configure(self.db, **sc.settings)
        with self.store.transaction():
            self.store.add_entity(sc.self_agent, "robot", is_self=True, t_ns=0)
            for agent in sc.agents:
                self.store.add_entity(agent, "human", t_ns=0)
            for obj in sc.objects:
                self.store.add_entity(obj, "object", t_ns=0)

    def _drop(self, subject: str, properties: tuple[str, ...]) -> None:
        for key in [k for k, f in self.state.items()
                    if f.subject_id == subject and f.property in properties]:
            del self.state[key]

    def apply(self, step: Step) -> None:
        """Apply one step to the world state and write it as one snapshot."""
        for entity, room in step.rooms.items():
            self._drop(entity, ("IsInRoom",))
            if room is not None:
                fact = Fact(entity, "IsInRoom", room)
                self.state[fact_key(fact)] = fact
        for entity, place in step.inside.items():
            self._drop(entity, ("IsIn", "IsOn"))
            if place is not None:
                fact = Fact(entity, place[0], place[1])
                self.state[fact_key(fact)] = fact
        for subject, prop, target in step.end:
            for key in [k for k, f in self.state.items() if f.subject_id == subject
                        and f.property == prop and (target is None or f.target_id == target)]:
                del self.state[key]
        for fact in step.facts:
            self.state[fact_key(fact)] = fact
        self.store.sync_snapshot(SOURCE, self.scenario.self_agent, step.t_ns,
                                 list(self.state.values()), actor=step.actor)
        for telling in step.tells:
            tell(self.db, telling.speaker, telling.fact, listeners=telling.listeners,
                 t_ns=step.t_ns)

    def run(self) -> None:
        """Set up and replay every step."""
        self.setup()
        for step in self.scenario.steps:
            self.apply(step)


def check(db: Any, scenario: Scenario) -> list[str]:
    """Evaluate the scenario's expectations; return one message per failure."""
    failures = []
    end = scenario.steps[-1].t_ns if scenario.steps else 0
    for i, exp in enumerate(scenario.expect, 1):
        t_ns = round(exp["t"] * 1e9) if "t" in exp else end
        row = api.belief_value(db, exp["agent"], exp["subject"], exp["property"],
                               exp.get("target", ""), about=exp.get("about"), at=t_ns)
        held = row is not None and row.value_text == str(exp.get("value", row.value_text))
        who = exp["agent"] + (f" about {exp['about']}" if exp.get("about") else "")
        what = f"{exp['subject']} {exp['property']} {exp.get('target', '')}".strip()
        if held != exp.get("held", True):
            failures.append(f"expectation {i}: {who} at t={t_ns / 1e9:g}s: {what} "
                            f"{'held' if held else 'not held'}, expected the opposite")
        elif (row is not None and held and "confidence" in exp
              and abs(row.confidence - exp["confidence"]) > 1e-9):
            failures.append(f"expectation {i}: {who}: {what} confidence {row.confidence:g}, "
                            f"expected {exp['confidence']:g}")
    return failures


def replay(db: Any, path_or_scenario: str | Path | Scenario) -> Scenario:
    """Load (if needed) and replay a scenario into ``db``; return it."""
    sc = (path_or_scenario if isinstance(path_or_scenario, Scenario)
          else load(path_or_scenario))
    Replayer(db, sc).run()
    return sc
