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
perceived change, the straightforward design, slower: see docs/beliefs.md).
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import Connection, text

from toaster.errors import InvalidInputError

SCOPE = "beliefs"
DEFAULTS: dict[str, Any] = {
    "enabled": True,
    "depth": 2,
    "copresence": ["IsInRoom"],
    "containment": ["IsIn", "IsOn"],
    "visibility": {"IsVisibleBy": "target", "CanSee": "subject", "IsLookingToward": "subject"},
    "closed": "IsClosed",
    "refute_by_target": ["IsOn"],
    "self_perception": False,
    "share_rows": True,
}
MAX_DEPTH = 4


def _str_list(key: str, value: object) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        msg = f"invalid beliefs setting {key}={value!r}: give a list of property names"
        raise InvalidInputError(msg)
    return value


def validate(key: str, value: object) -> object:
    """Check one setting; return it or raise a one-line :class:`InvalidInputError`."""
    if key not in DEFAULTS:
        msg = f"unknown beliefs setting {key!r}: use one of {', '.join(sorted(DEFAULTS))}"
        raise InvalidInputError(msg)
    if key in ("enabled", "self_perception", "share_rows") and not isinstance(value, bool):
        msg = f"invalid beliefs setting {key}={value!r}: use true or false"
        raise InvalidInputError(msg)
    if key == "depth" and (not isinstance(value, int) or isinstance(value, bool)
                           or not 1 <= value <= MAX_DEPTH):
        msg = f"invalid beliefs setting depth={value!r}: use an integer from 1 to {MAX_DEPTH}"
        raise InvalidInputError(msg)
    if key in ("copresence", "containment", "refute_by_target"):
        _str_list(key, value)
    if key == "visibility" and (not isinstance(value, dict) or any(
            not isinstance(k, str) or v not in ("subject", "target") for k, v in value.items())):
        msg = (f"invalid beliefs setting visibility={value!r}: map each property to "
               "'subject' or 'target' (the side that sees)")
        raise InvalidInputError(msg)
    if key == "closed" and (not isinstance(value, str) or not value):
        msg = f"invalid beliefs setting closed={value!r}: give a property name"
        raise InvalidInputError(msg)
    return value


def read(conn: Connection) -> dict[str, Any]:
    """The current configuration (defaults filled in) in one query."""
    import json

    rows = conn.execute(text("SELECT key, value_json FROM settings WHERE scope = :s"),
                        {"s": SCOPE}).all()
    config = dict(DEFAULTS)
    config.update({key: json.loads(body) for key, body in rows})
    return config


def perception_properties(config: dict[str, Any]) -> frozenset[str]:
    """Properties whose change can change who perceives what (triggers "seeing again")."""
    return frozenset([*config["copresence"], *config["containment"], *config["visibility"],
                      config["closed"]])
