"""Belief scenarios: timed facts and room changes replayed without geometry.

A scenario file (YAML or JSON)::

    name: sally-anne
    self: ROBOT                     # the self agent (a robot), registered for you
    agents: [SALLY, ANNE]           # humans
    objects: [MARBLE, BASKET, BOX, ROOM]
    settings: {depth: 2}            # optional belief settings (see toaster.rules.settings)
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
from typing import TYPE_CHECKING, Any

from toaster.beliefs import api
from toaster.beliefs.tell import tell
from toaster.db.catalog import note_data_start
from toaster.documents import located, read_document
from toaster.errors import FileFormatError, InvalidInputError
from toaster.model import (
    Fact,
    check_fact,
    check_id,
    check_text,
    check_unit_interval,
    fact_key,
    shown,
)
from toaster.rules import settings as cfg
from toaster.timeutil import MAX_NS, check_ns

if TYPE_CHECKING:
    from toaster.db.database import Database

SOURCE = "scenario"
_FACT_FIELDS = (
    "subject",
    "property",
    "target",
    "value",
    "value_num",
    "confidence",
    "observability",
)


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


_STEP_KEYS = ("t", "t_ns", "rooms", "inside", "onto", "facts", "end", "actor", "tell")
_EXPECT_KEYS = (
    "t",
    "agent",
    "about",
    "subject",
    "property",
    "target",
    "value",
    "held",
    "confidence",
)


def _bad(where: str, value: object, fix: str) -> FileFormatError:
    return FileFormatError(f"{where}: invalid {shown(value)}: {fix}")


def _id(where: str, value: object, what: str = "id") -> str:
    """An id (numbers written as text), or a one-line error naming ``where``."""
    if isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    with located(where):
        return check_id(value, what)


def _ids(where: str, raw: object, what: str) -> list[str]:
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise _bad(where, raw, f"{what} is a list of ids")
    return [_id(where, v, what) for v in raw]


def _seconds_ns(where: str, value: object) -> int:
    """Seconds (a finite number) as nanoseconds in the database's range."""
    try:
        ok = (
            isinstance(value, int | float)
            and not isinstance(value, bool)
            and math.isfinite(value)
            and 0 <= value <= MAX_NS / 1e9
        )
    except OverflowError:
        ok = False
    if not ok:
        raise _bad(where, value, "t is seconds from 0 (t_ns: integer nanoseconds)")
    return check_ns(round(value * 1e9))  # type: ignore[operator]


def _time(where: str, raw: dict[str, Any]) -> int:
    if "t_ns" in raw:
        value = raw["t_ns"]
        if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= MAX_NS:
            return value
        raise _bad(where, value, "t_ns must be an integer number of nanoseconds from 0 to 2^63-1")
    value = raw.get("t")
    if not isinstance(value, int | float) or isinstance(value, bool):
        raise _bad(where, value, "give t (seconds) or t_ns (integer nanoseconds) for every step")
    return _seconds_ns(where, value)


def _scalar(where: str, value: object, what: str) -> str:
    if isinstance(value, bool):
        value = str(value).lower()
    elif isinstance(value, int | float):
        value = str(value)
    with located(where):
        return check_text(value, what)


def _fact(where: str, raw: object) -> Fact:
    if isinstance(raw, list | tuple) and 2 <= len(raw) <= 4:
        raw = dict(zip(("subject", "property", "target", "value"), raw, strict=False))
    if not isinstance(raw, dict) or "subject" not in raw or "property" not in raw:
        raise _bad(
            where,
            raw,
            "write a fact as [SUBJECT, PROPERTY, TARGET] or "
            "{subject: S, property: P, target: T, value: V, confidence: C}",
        )
    unknown = set(raw) - set(_FACT_FIELDS)
    if unknown:
        raise _bad(
            where, sorted(map(str, unknown))[0], f"fact fields are {', '.join(_FACT_FIELDS)}"
        )
    target = raw.get("target")
    try:
        return check_fact(
            Fact(
                _id(where, raw["subject"], "subject"),
                _id(where, raw["property"], "property"),
                "" if target in (None, "") else _id(where, target, "target"),
                _scalar(where, raw.get("value", "true"), "value"),
                raw.get("value_num"),
                raw.get("confidence", 1.0),
                raw.get("observability", 1.0),
            )
        )
    except InvalidInputError as exc:
        if isinstance(exc, FileFormatError):
            raise
        msg = f"{where}: {exc}"
        raise FileFormatError(msg) from None


def _mapping(where: str, raw: object) -> dict[str, str | None]:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise _bad(where, raw, "give a mapping ENTITY: PLACE (null = none)")
    return {
        _id(where, k, "entity"): (None if v is None else _id(where, v, "place"))
        for k, v in raw.items()
    }


def _tells(where: str, raw: object, agents: set[str]) -> list[Telling]:
    items = [] if raw is None else raw if isinstance(raw, list) else [raw]
    tells = []
    for item in items:
        if (
            not isinstance(item, dict)
            or not isinstance(item.get("speaker"), str)
            or "fact" not in item
            or set(item) - {"speaker", "listeners", "public", "fact"}
        ):
            raise _bad(
                where,
                item,
                "write a telling as {speaker: ID, listeners: [ID, ...], "
                "fact: [SUBJECT, PROPERTY, TARGET]} (or public: true for the room)",
            )
        speaker = _agent(where, item["speaker"], agents, "speaker")
        listeners = item.get("listeners")
        if not isinstance(item.get("public", False), bool):
            raise _bad(where, item["public"], "public is true or false")
        if item.get("public"):
            listeners = None
        elif not isinstance(listeners, list) or not listeners:
            raise _bad(where, listeners, "give listeners: [ID, ...] or public: true")
        tells.append(
            Telling(
                speaker,
                _fact(where, item["fact"]),
                None
                if listeners is None
                else [_agent(where, v, agents, "listener") for v in listeners],
            )
        )
    return tells


def _agent(where: str, value: object, agents: set[str], what: str) -> str:
    """An id of the scenario's self or agents."""
    agent = _id(where, value, what)
    if agent not in agents:
        raise _bad(
            where,
            agent,
            f"the {what} must be the self or one of the agents ({', '.join(sorted(agents))})",
        )
    return agent


def _step(where: str, raw: object, agents: set[str]) -> Step:
    if not isinstance(raw, dict):
        raise _bad(where, raw, "each step is a mapping with t and changes")
    unknown = set(raw) - set(_STEP_KEYS)
    if unknown:
        raise _bad(where, sorted(map(str, unknown))[0], f"a step has {', '.join(_STEP_KEYS)}")
    step = Step(_time(where, raw), rooms=_mapping(where, raw.get("rooms")))
    for word, prop in (("inside", "IsIn"), ("onto", "IsOn")):
        for entity, place in _mapping(where, raw.get(word)).items():
            step.inside[entity] = None if place is None else (prop, place)
    facts = raw.get("facts") or []
    if not isinstance(facts, list):
        raise _bad(where, facts, "facts is a list of facts")
    step.facts = [_fact(where, f) for f in facts]
    ends = raw.get("end") or []
    if not isinstance(ends, list):
        raise _bad(
            where, ends, "end is a list of [SUBJECT, PROPERTY] or [SUBJECT, PROPERTY, TARGET]"
        )
    for item in ends:
        if not isinstance(item, list | tuple) or not 2 <= len(item) <= 3:
            raise _bad(
                where, item, "end a fact with [SUBJECT, PROPERTY] or [SUBJECT, PROPERTY, TARGET]"
            )
        step.end.append(
            (
                _id(where, item[0], "subject"),
                _id(where, item[1], "property"),
                _id(where, item[2], "target") if len(item) == 3 else None,
            )
        )
    actor = raw.get("actor")
    if actor is not None:
        actor = _agent(where, actor, agents, "actor")
    step.actor = actor
    step.tells = _tells(where, raw.get("tell"), agents)
    return step


def _expectation(where: str, raw: object, holders: set[str]) -> dict[str, Any]:
    """One expectation, checked: ids, t (seconds), held (bool), value, confidence."""
    if not isinstance(raw, dict) or not {"agent", "subject", "property"} <= set(raw):
        raise _bad(
            where,
            raw,
            "write an expectation as {t: 4, agent: A, subject: S, "
            "property: P, target: T[, about: B, held: false, value: V]}",
        )
    unknown = set(raw) - set(_EXPECT_KEYS)
    if unknown:
        raise _bad(
            where, sorted(map(str, unknown))[0], f"an expectation has {', '.join(_EXPECT_KEYS)}"
        )
    out: dict[str, Any] = {
        key: _id(where, raw[key], key) for key in ("agent", "subject", "property")
    }
    _agent(where, out["agent"], holders, "agent")
    if raw.get("target") not in (None, ""):
        out["target"] = _id(where, raw["target"], "target")
    about = raw.get("about")
    if about is not None:
        out["about"] = (
            _agent(where, about, holders, "about")
            if not isinstance(about, list)
            else [_agent(where, a, holders, "about") for a in about]
        )
    if "t" in raw:
        out["t_ns"] = _seconds_ns(where, raw["t"])
    if "held" in raw:
        if not isinstance(raw["held"], bool):
            raise _bad(where, raw["held"], "held is true or false")
        out["held"] = raw["held"]
    if "value" in raw:
        out["value"] = _scalar(where, raw["value"], "value")
    if "confidence" in raw:
        try:
            out["confidence"] = check_unit_interval(raw["confidence"], "confidence")
        except InvalidInputError as exc:
            msg = f"{where}: {exc}"
            raise FileFormatError(msg) from None
    return out


def parse(data: object, name: str = "scenario") -> Scenario:
    """Validate a loaded YAML/JSON document into a :class:`Scenario`, every field checked."""
    if not isinstance(data, dict) or not isinstance(data.get("steps"), list):
        raise _bad(name, type(data).__name__, "a scenario is a mapping with a list of steps")
    self_agent = _id(name, data.get("self", "ROBOT"), "self")
    agents = _ids(name, data.get("agents"), "agents")
    objects = _ids(name, data.get("objects"), "objects")
    declared = [self_agent, *agents, *objects]
    twice = sorted({i for i in declared if declared.count(i) > 1})
    if twice:
        raise _bad(name, twice[0], "self, agents and objects name each id once")
    settings = data.get("settings") or {}
    if not isinstance(settings, dict):
        raise _bad(name, settings, "settings map belief settings to values, e.g. {depth: 2}")
    try:
        for key, value in settings.items():
            cfg.validate(key, value)
    except InvalidInputError as exc:
        msg = f"{name}: settings: {exc}"
        raise FileFormatError(msg) from None
    holders = {self_agent, *agents}
    steps: list[Step] = []
    for i, raw in enumerate(data["steps"], 1):
        where = f"{name}: step {i}"
        step = _step(where, raw, holders)
        if steps and step.t_ns < steps[-1].t_ns:
            raise _bad(where, raw.get("t", raw.get("t_ns")), "steps must be in time order")
        steps.append(step)
    expect = data.get("expect") or []
    if not isinstance(expect, list):
        raise _bad(name, expect, "expect is a list of expectations")
    title = data.get("name", name)
    return Scenario(
        _scalar(name, title, "name"),
        self_agent,
        agents,
        objects,
        dict(settings),
        steps,
        [_expectation(f"{name}: expectation {i}", e, holders) for i, e in enumerate(expect, 1)],
    )


def load(path: str | Path) -> Scenario:
    """Read a scenario file (``.yaml``/``.yml`` or ``.json``)."""
    path = Path(path)
    return parse(read_document(path, "scenario"), path.name)


class Replayer:
    """Replays steps as snapshots of the self agent, keeping the world state between them."""

    def __init__(self, db: Database, scenario: Scenario) -> None:
        self.db, self.scenario = db, scenario
        self.store = db.store()
        self.state: dict[tuple[str, ...], Fact] = {}

    def setup(self) -> None:
        """Register the entities and apply the scenario's settings; its times count from 0,
        the data's start."""
        sc = self.scenario
        if sc.settings:
            api.configure(self.db, **sc.settings)
        with self.store.transaction() as conn:
            note_data_start(conn, 0)
            self.store.add_entity(sc.self_agent, "robot", is_self=True, t_ns=0)
            for agent in sc.agents:
                self.store.add_entity(agent, "human", t_ns=0)
            for obj in sc.objects:
                self.store.add_entity(obj, "object", t_ns=0)

    def _drop(self, subject: str, properties: tuple[str, ...]) -> None:
        for key in [
            k for k, f in self.state.items() if f.subject_id == subject and f.property in properties
        ]:
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
            for key in [
                k
                for k, f in self.state.items()
                if f.subject_id == subject
                and f.property == prop
                and (target is None or f.target_id == target)
            ]:
                del self.state[key]
        for fact in step.facts:
            self.state[fact_key(fact)] = fact
        self.store.sync_snapshot(
            SOURCE, self.scenario.self_agent, step.t_ns, list(self.state.values()), actor=step.actor
        )
        for telling in step.tells:
            tell(
                self.db, telling.speaker, telling.fact, listeners=telling.listeners, t_ns=step.t_ns
            )

    def run(self) -> None:
        """Set up and replay every step, in one transaction (all or nothing)."""
        with self.store.transaction():
            self.setup()
            for step in self.scenario.steps:
                self.apply(step)


def check(db: Database, scenario: Scenario) -> list[str]:
    """Evaluate the scenario's expectations; return one message per failure."""
    failures = []
    end = scenario.steps[-1].t_ns if scenario.steps else 0
    for i, exp in enumerate(scenario.expect, 1):
        t_ns = exp.get("t_ns", round(exp["t"] * 1e9) if "t" in exp else end)
        row = api.belief_value(
            db,
            exp["agent"],
            exp["subject"],
            exp["property"],
            exp.get("target", ""),
            about=exp.get("about"),
            at=t_ns,
        )
        held = row is not None and row.value_text == str(exp.get("value", row.value_text))
        who = exp["agent"] + (f" about {exp['about']}" if exp.get("about") else "")
        what = f"{exp['subject']} {exp['property']} {exp.get('target', '')}".strip()
        if held != exp.get("held", True):
            failures.append(
                f"expectation {i}: {who} at t={t_ns / 1e9:g}s: {what} "
                f"{'held' if held else 'not held'}, expected the opposite"
            )
        elif (
            row is not None
            and held
            and "confidence" in exp
            and abs(row.confidence - exp["confidence"]) > 1e-9
        ):
            failures.append(
                f"expectation {i}: {who}: {what} confidence {row.confidence:g}, "
                f"expected {exp['confidence']:g}"
            )
    return failures


def replay_and_check(
    db: Database, path_or_scenario: str | Path | Scenario
) -> tuple[Scenario, list[str]]:
    """:func:`replay` then :func:`check`, in one transaction: an error in either (an
    expectation about a holder deeper than the depth setting...) writes nothing."""
    sc = path_or_scenario if isinstance(path_or_scenario, Scenario) else load(path_or_scenario)
    with db.store().transaction():
        Replayer(db, sc).run()
        return sc, check(db, sc)


def replay(db: Database, path_or_scenario: str | Path | Scenario) -> Scenario:
    """Load (if needed) and replay a scenario into ``db``; return it."""
    sc = path_or_scenario if isinstance(path_or_scenario, Scenario) else load(path_or_scenario)
    Replayer(db, sc).run()
    return sc
