"""Belief-rule configuration, kept as data in ``settings`` (scope ``beliefs``).

Keys: ``enabled`` (bool), ``depth`` (1 = first order only, 2 = "A thinks B believes", ...),
``copresence`` (properties placing an entity in a room, default ``["IsInRoom"]``),
``containment`` (properties placing an entity in/on another one, default ``["IsIn", "IsOn"]``),
``visibility`` (property -> which side perceives: ``"subject"`` for CanSee / IsLookingToward,
``"target"`` for IsVisibleBy), ``closed`` (the property marking a closed container, default
``"IsClosed"``), ``refute_by_target`` (properties refuted by seeing the target alone, original
issue #24, default ``["IsOn"]``), ``self_perception`` (an agent perceives facts about
itself wherever it is, default false), ``share_rows`` (a holder whose belief follows the self
agent's reads the self's rows instead of copying them, default true; false copies every
perceived change, the straightforward design, slower: see docs/beliefs.md), ``attention``
(copresence property -> attention properties that must also hold for an agent in the room to
perceive, e.g. ``{"IsInRoom": ["IsLookingToward", "IsAttentive"]}``; default ``{}``: being
in the room is enough), ``trust`` (whom a listener believes when told something:
``"everyone"``, the default, or ``"witnesses"``: a speaker who perceived the subject later
than the listener did) and ``distrust`` (agents never believed, default ``[]``); revision 0009.
``group_holders`` (holders that perceive alike share the rule's work, default true; false
computes every holder alone, same beliefs, slower: revision 0011).
"""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import Connection, text

from toaster.errors import InvalidInputError

SCOPE = "beliefs"
#: The settings and the kind of value each takes. Their defaults live in the database (view
#: ``belief_settings``, migration 0006), read by the rule statements and by :func:`read` alike.
KINDS: dict[str, str] = {
    "enabled": "bool",
    "depth": "depth",
    "copresence": "properties",
    "containment": "properties",
    "visibility": "sides",
    "closed": "property",
    "refute_by_target": "properties",
    "self_perception": "bool",
    "share_rows": "bool",
    "attention": "gates",
    "trust": "trust",
    "distrust": "agents",
    "group_holders": "bool",
}
TRUST_POLICIES = ("everyone", "witnesses")
MAX_DEPTH = 4


def _str_list(key: str, value: object) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        msg = f"invalid beliefs setting {key}={value!r}: give a list of property names"
        raise InvalidInputError(msg)
    return value


def validate(key: str, value: object) -> object:
    """Check one setting; return it or raise a one-line :class:`InvalidInputError`."""
    kind = KINDS[check_key(key)]
    if kind == "bool" and not isinstance(value, bool):
        msg = f"invalid beliefs setting {key}={value!r}: use true or false"
        raise InvalidInputError(msg)
    if kind == "depth" and (
        not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= MAX_DEPTH
    ):
        msg = f"invalid beliefs setting depth={value!r}: use an integer from 1 to {MAX_DEPTH}"
        raise InvalidInputError(msg)
    if kind == "properties":
        _str_list(key, value)
    if kind == "sides" and (
        not isinstance(value, dict)
        or any(not isinstance(k, str) or v not in ("subject", "target") for k, v in value.items())
    ):
        msg = (
            f"invalid beliefs setting visibility={value!r}: map each property to "
            "'subject' or 'target' (the side that sees)"
        )
        raise InvalidInputError(msg)
    if kind == "gates" and (
        not isinstance(value, dict)
        or any(
            not isinstance(k, str)
            or not k
            or not isinstance(v, list)
            or not all(isinstance(a, str) and a for a in v)
            for k, v in value.items()
        )
    ):
        msg = (
            f"invalid beliefs setting attention={value!r}: map a copresence property to a "
            'list of attention properties, e.g. {"IsInRoom": ["IsLookingToward"]}'
        )
        raise InvalidInputError(msg)
    if kind == "trust" and value not in TRUST_POLICIES:
        msg = f"invalid beliefs setting trust={value!r}: use one of {', '.join(TRUST_POLICIES)}"
        raise InvalidInputError(msg)
    if kind == "agents" and (
        not isinstance(value, list) or not all(isinstance(v, str) and v for v in value)
    ):
        msg = f"invalid beliefs setting {key}={value!r}: give a list of agent ids"
        raise InvalidInputError(msg)
    if kind == "property" and (not isinstance(value, str) or not value):
        msg = f"invalid beliefs setting closed={value!r}: give a property name"
        raise InvalidInputError(msg)
    return value


def read(conn: Connection) -> dict[str, Any]:
    """The current configuration, defaults filled in by the database, in one query."""
    rows = conn.execute(text("SELECT key, value_json FROM belief_settings")).all()
    return {key: json.loads(body) for key, body in rows}


def check_key(key: str) -> str:
    """``key`` if it names a setting, else a one-line :class:`InvalidInputError`."""
    if key not in KINDS:
        msg = f"unknown beliefs setting {key!r}: use one of {', '.join(sorted(KINDS))}"
        raise InvalidInputError(msg)
    return key


def perception_properties(config: dict[str, Any]) -> frozenset[str]:
    """Properties whose change can change who perceives what (triggers "seeing again")."""
    return frozenset(
        [
            *config["copresence"],
            *config["containment"],
            *config["visibility"],
            *(a for gate in config["attention"].values() for a in gate),
            config["closed"],
        ]
    )
