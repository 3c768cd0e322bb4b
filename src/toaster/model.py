"""Plain value types shared by the store, the queries and the producers (no SQLAlchemy here).

A :class:`Fact` is what a producer or a user states; a :class:`FactRow` is one validity interval
of a fact as stored for one agent; an :class:`EventRow` is one change of an agent's beliefs.
All are NamedTuples: cheap to build in bulk, comparable, and easy to turn into dicts or frames.
"""

from __future__ import annotations

import bisect
import builtins
import math
import re
from collections.abc import Iterable
from typing import NamedTuple

from toaster.errors import InvalidInputError

#: Kinds of entity the original knew; other words are accepted and kept lower-case.
AGENT_KINDS = frozenset({"human", "robot"})
ENTITY_KINDS = frozenset({"human", "robot", "object", "joint", "area", "agent", ""})

#: Event kinds written by the store; ``event`` is a user-recorded event (set-info EVENT).
EVENT_KINDS = ("appeared", "changed", "ended", "event")


class FactKey(NamedTuple):
    """The identity of a fact for one agent (the agent itself is kept beside it)."""

    subject_id: str
    subject_owner_id: str
    property: str
    sub_property: str
    target_id: str
    target_owner_id: str


class Fact(NamedTuple):
    """A statement a source holds true: "SUBJECT PROPERTY TARGET" with its value and confidence.

    Only ``subject_id`` and ``property`` are required. ``target_id`` is ``""`` for facts without
    a target (IsMoving). ``value_text`` is the symbolic value: a change of it ends one interval
    and starts the next; ``value_num`` and ``confidence`` refresh the current interval.
    """

    subject_id: str
    property: str
    target_id: str = ""
    value_text: str = "true"
    value_num: float | None = None
    confidence: float = 1.0
    observability: float = 1.0
    property_type: str = ""
    sub_property: str = ""
    subject_owner_id: str = ""
    target_owner_id: str = ""

    @builtins.property  # the field ``property`` hides the builtin here
    def key(self) -> FactKey:
        """The identity of this fact (owners included, value excluded)."""
        return FactKey(
            self.subject_id,
            self.subject_owner_id,
            self.property,
            self.sub_property,
            self.target_id,
            self.target_owner_id,
        )


def fact_key(fact: Fact) -> tuple[str, str, str, str, str, str]:
    """Fast identity tuple of a fact, in :class:`FactKey` order."""
    return (fact[0], fact[9], fact[1], fact[8], fact[2], fact[10])


class FactRow(NamedTuple):
    """One validity interval of a fact held by ``agent_id``; ``valid_to_ns`` None = current."""

    agent_id: str
    subject_id: str
    subject_owner_id: str
    property: str
    property_type: str
    sub_property: str
    target_id: str
    target_owner_id: str
    value_text: str
    value_num: float | None
    confidence: float
    observability: float
    valid_from_ns: int
    valid_to_ns: int | None
    recorded_ns: int
    source: str

    @builtins.property  # the field ``property`` hides the builtin here
    def is_current(self) -> bool:
        """True while the interval is open."""
        return self.valid_to_ns is None

    def to_fact(self) -> Fact:
        """The statement this row holds (without agent and interval)."""
        return Fact(
            self.subject_id,
            self.property,
            self.target_id,
            self.value_text,
            self.value_num,
            self.confidence,
            self.observability,
            self.property_type,
            self.sub_property,
            self.subject_owner_id,
            self.target_owner_id,
        )


class NumberedInterval(NamedTuple):
    """One interval and the numbers it had before each stored refresh: ``(until_ns, value_num,
    confidence, observability)``, oldest first, each held from the previous one's ``until_ns``
    (the first from the interval's start) until its own; after the last, the interval's own
    numbers hold."""

    row: FactRow
    numbers: tuple[tuple[int, float | None, float, float], ...]

    def at(self, t_ns: int) -> FactRow:
        """The interval with the numbers it had at ``t_ns`` (within its tolerance): the first
        stored refresh after ``t_ns``, found by bisection (a recording asks at every frame)."""
        i = bisect.bisect_right(self.numbers, t_ns, key=lambda number: number[0])
        if i == len(self.numbers):
            return self.row
        _, value, confidence, observability = self.numbers[i]
        return self.row._replace(
            value_num=value, confidence=confidence, observability=observability
        )


class EventRow(NamedTuple):
    """One change of an agent's beliefs (or a user-recorded event)."""

    id: int
    agent_id: str
    kind: str
    stamp_ns: int
    subject_id: str
    subject_owner_id: str
    property: str
    property_type: str
    sub_property: str
    target_id: str
    target_owner_id: str
    value_text: str | None
    value_num: float | None
    confidence: float | None
    observability: float | None
    previous_text: str | None
    source: str
    recorded_ns: int


class Entity(NamedTuple):
    """A thing the world model knows: human, robot, object, joint (with owner), area..."""

    id: str
    name: str
    kind: str
    owner_id: str


class Agent(NamedTuple):
    """An entity that holds beliefs; ``is_self`` agents believe the world state."""

    id: str
    is_self: bool
    fact_view: str
    memory_view: str
    events_view: str


class OntologyRow(NamedTuple):
    """One edge of the class tree: ``individual`` is a child of ``entity_class``."""

    entity_class: str
    individual: str
    instantiated: bool


class PropertyRow(NamedTuple):
    """A static property of an entity (open key/value)."""

    entity_id: str
    key: str
    value: str


#: The longest id (entity, agent, property, area, setting key...) in bytes of UTF-8: 256 ASCII
#: characters, 64 emoji. PostgreSQL's btree index rows hold at most 2704 bytes, and the
#: widest index, a fact key of a nested holder ``A>B>C>D`` (depth 4), takes 10 ids.
MAX_ID_BYTES = 256
#: The characters ``str.isspace`` finds (an id made only of them is refused; the database's
#: inbox check lists them too: ``rules.sqltext``).
SPACES = (
    "\t\n\x0b\x0c\r\x1c\x1d\x1e\x1f \x85\xa0\u1680\u2000\u2001\u2002\u2003\u2004\u2005"
    "\u2006\u2007\u2008\u2009\u200a\u2028\u2029\u202f\u205f\u3000"
)
#: Coordinates (metres) beyond this are refused in files: a world of 2000 km across is plenty.
MAX_COORD = 1e6
_SURROGATE = re.compile("[\ud800-\udfff]")


def shown(value: object) -> str:
    """``repr(value)``, cut to 60 characters for messages."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:45]}...({len(text)} chars)"


def listed(names: Iterable[object], most: int = 10, none: str = "none") -> str:
    """Names for a message: each shown as :func:`shown` does, at most ``most`` of them and
    then how many more (a crowd's thousands of agents), ``none`` when there is none."""
    items = list(names)
    if not items:
        return none
    head = ", ".join(shown(item) for item in items[:most])
    return head if len(items) <= most else f"{head} and {len(items) - most} more"


def check_text(value: object, what: str) -> str:
    """Return ``value`` if it is text a database can store (no NUL, no lone surrogate, which
    non-UTF-8 bytes of a file name or argument become), else raise a one-line error."""
    if not isinstance(value, str):
        msg = f"invalid {what} {shown(value)}: it must be text"
        raise InvalidInputError(msg)
    if not value.isascii() and _SURROGATE.search(value):
        msg = (
            f"invalid {what} {shown(value)}: it is not valid UTF-8 text "
            "(undecodable bytes); give UTF-8"
        )
        raise InvalidInputError(msg)
    if "\x00" in value:
        msg = f"invalid {what} {shown(value)}: it holds a NUL character; remove it"
        raise InvalidInputError(msg)
    return value


def utf8_size(text: str) -> int:
    """Bytes of ``text`` in UTF-8 (valid text: see :func:`check_text`)."""
    return len(text) if text.isascii() else len(text.encode("utf-8", "surrogatepass"))


def check_id(value: object, what: str) -> str:
    """Return ``value`` if it is a valid id: non-empty text without NUL or lone surrogates, of
    at most :data:`MAX_ID_BYTES` bytes of UTF-8; else raise a one-line error. Every id that
    enters the database passes here."""
    if not isinstance(value, str) or not value.strip():
        msg = f"invalid {what} {shown(value)}: ids must be non-empty text"
        raise InvalidInputError(msg)
    size = utf8_size(value)
    if size > MAX_ID_BYTES:
        msg = (
            f"invalid {what} {shown(value)}: ids are at most {MAX_ID_BYTES} bytes of UTF-8 "
            f"({MAX_ID_BYTES} ASCII characters), not {size}; use a shorter id"
        )
        raise InvalidInputError(msg)
    return check_text(value, what)


def check_list(value: object, what: str) -> list[object]:
    """``value``'s items if it is a list, tuple or set (not text), else a one-line error."""
    if not isinstance(value, list | tuple | set | frozenset):
        msg = f"invalid {what} {shown(value)}: give a list"
        raise InvalidInputError(msg)
    return list(value)


#: Joins the agents of a nested belief holder: ``ANNE>SALLY`` is Anne's model of Sally.
HOLDER_SEPARATOR = ">"


def check_agent_id(value: object, what: str = "agent id") -> str:
    """``value`` if it is a valid id (:func:`check_id`) an agent may have: without
    :data:`HOLDER_SEPARATOR`, which would make it a nested holder's id."""
    agent = check_id(value, what)
    if HOLDER_SEPARATOR in agent:
        msg = (
            f"invalid {what} {shown(value)}: {HOLDER_SEPARATOR!r} joins nested belief "
            f"holders (ANNE{HOLDER_SEPARATOR}SALLY is Anne's model of Sally); an agent's "
            "id cannot hold it: rename the agent"
        )
        raise InvalidInputError(msg)
    return agent


def check_optional_id(value: object, what: str) -> str:
    """``value`` if it is ``""`` (none) or a valid id (:func:`check_id`)."""
    return value if value == "" else check_id(value, what)


def check_unit_interval(value: object, what: str) -> float:
    """Return ``value`` as a float in [0, 1], else raise a one-line error naming it."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not (0.0 <= number <= 1.0):
        msg = f"invalid {what} {value!r}: it must be a number between 0 and 1"
        raise InvalidInputError(msg)
    return number


_KEY_FIELDS = (
    "subject_id",
    "property",
    "target_id",
    "sub_property",
    "subject_owner_id",
    "target_owner_id",
)
_TEXT_FIELDS = ("value_text", "property_type")


def _plain(fact: object) -> bool:
    """True for a Fact whose fields already have the right types and ranges (fast path: ASCII
    texts without NUL, ids of at most MAX_ID_BYTES)."""
    if type(fact) is not Fact:
        return False
    s, p, t, vt, vn, c, o, pt, sp, so, to = fact  # type: ignore[misc]
    if not (
        type(s) is str
        and type(p) is str
        and type(t) is str
        and type(vt) is str
        and type(pt) is str
        and type(sp) is str
        and type(so) is str
        and type(to) is str
        and type(c) is float
        and 0.0 <= c <= 1.0
        and type(o) is float
        and 0.0 <= o <= 1.0
        and (vn is None or (type(vn) is float and math.isfinite(vn)))
        and bool(s)
        and bool(p)
        and not s.isspace()
        and not p.isspace()
    ):
        return False
    key = s + p + t + sp + so + to
    return (
        len(s) <= MAX_ID_BYTES
        and len(p) <= MAX_ID_BYTES
        and len(t) <= MAX_ID_BYTES
        and len(sp) <= MAX_ID_BYTES
        and len(so) <= MAX_ID_BYTES
        and len(to) <= MAX_ID_BYTES
        and key.isascii()
        and "\x00" not in key
        and vt.isascii()
        and pt.isascii()
        and "\x00" not in vt
        and "\x00" not in pt
    )


def check_fact(fact: Fact) -> Fact:
    """Validate one fact (ids, texts, confidence, observability, numeric value); return it
    normalised."""
    if _plain(fact):
        return fact
    if not isinstance(fact, Fact):
        if isinstance(fact, tuple) and 2 <= len(fact) <= len(Fact._fields):
            fact = Fact(*fact)
        else:
            msg = f"invalid fact {shown(fact)}: give a toaster.Fact(subject_id, property, ...)"
            raise InvalidInputError(msg)
    check_id(fact.subject_id, "subject id")
    check_id(fact.property, "property")
    for name in _KEY_FIELDS[2:]:
        check_optional_id(getattr(fact, name), f"{name} in {fact.subject_id} {fact.property}")
    for name in _TEXT_FIELDS:
        check_text(getattr(fact, name), f"{name} in {fact.subject_id} {fact.property}")
    confidence = check_unit_interval(fact.confidence, "confidence")
    observability = check_unit_interval(fact.observability, "observability")
    value_num = fact.value_num
    if value_num is not None:
        try:
            value_num = float(value_num)
        except (TypeError, ValueError):
            value_num = math.nan
        if not math.isfinite(value_num):
            msg = (
                f"invalid numeric value {fact.value_num!r} for {fact.subject_id} "
                f"{fact.property}: must be finite"
            )
            raise InvalidInputError(msg)
    # (1 == 1.0: compared by value, an int confidence would stay an int, which PostgreSQL's
    # float arrays refuse beside floats)
    return fact._replace(confidence=confidence, observability=observability, value_num=value_num)
