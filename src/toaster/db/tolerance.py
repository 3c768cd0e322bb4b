"""Tolerances of continuous values, kept as data in ``settings`` (scope ``tolerance``).

A fact's number (``value_num``), confidence and observability are *signals*: a change within
the property's tolerance is not written; beyond it, the open interval is refreshed and the
values it held until then go to ``fact_samples``. The stored value of a key therefore never
differs from the true one by more than the tolerance, at any past time (see docs/store.md).

Keys are property names, or ``*`` for every other property; a value is a mapping
``{"value": 0.05, "confidence": 0.05, "observability": 0.0}`` (missing parts keep the
default's) or one number (the value tolerance). Units are the property's own: metres for
Distance, m/s for IsMoving, radians for IsLookingToward, and so on. ``*`` defaults to 0: a
number stated through the API is stored exactly unless a tolerance is set for it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NamedTuple

from sqlalchemy import Connection

from toaster.db import catalog
from toaster.errors import InvalidInputError

SCOPE = "tolerance"
PARTS = ("value", "confidence", "observability")


class Tolerance(NamedTuple):
    """Largest unwritten change of each numeric part of a fact (absolute, ≥ 0)."""

    value: float = 0.0
    confidence: float = 0.0
    observability: float = 0.0


EXACT = Tolerance()
#: Defaults of the producers' continuous facts (units: see each property in docs/producers.md).
DEFAULTS: dict[str, Tolerance] = {
    "*": EXACT,
    "Distance": Tolerance(0.05, 0.05),  # metres: a quarter of the "close" band (0.2 m)
    # Speeds and approach figures come from 0.25-0.5 s windows: with 2 cm of tracker noise at
    # 30 Hz a speed has ~0.11 m/s of noise, so a tighter tolerance records the noise itself
    # (docs/store.md, "Continuous values").
    "IsMoving": Tolerance(0.25, 0.2),  # m/s; confidence = speed x 0.72 s/m
    # direction: value = confidence = 1 - |deviation| / 1 rad (the original's); distance:
    # metres approached over the window, confidence = its share of the step: volatile pairs
    "IsMovingToward": Tolerance(0.3, 0.3),
    "IsLookingToward": Tolerance(0.05, 0.05),  # radians: 3 degrees
    "IsLookingAt": Tolerance(0.05, 0.05),
    "IsVisibleBy": Tolerance(0.0, 0.1),  # the visible share of 5 sample points: 0.2 steps
    "CanSee": Tolerance(0.0, 0.1),
    "AreaDensity": Tolerance(0.0, 0.05),
}


def parse(prop: str, raw: object, base: Tolerance = EXACT) -> Tolerance:
    """A setting's value as a :class:`Tolerance` (one-line error naming the bad part)."""
    parts = dict(base._asdict())
    if isinstance(raw, Mapping):
        unknown = set(raw) - set(PARTS)
        if unknown:
            msg = (
                f"invalid tolerance for {prop}: unknown part {sorted(unknown)[0]!r}; "
                f"use {', '.join(PARTS)}"
            )
            raise InvalidInputError(msg)
        parts.update(raw)
    else:
        parts["value"] = raw
    for part, value in parts.items():
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
            or value < 0
        ):
            msg = (
                f"invalid tolerance {value!r} for {prop} {part}: give a number ≥ 0 "
                "in the property's unit"
            )
            raise InvalidInputError(msg)
    return Tolerance(*(float(parts[p]) for p in PARTS))


def validate(prop: str, raw: object) -> object:
    """Check one setting before it is stored; return it unchanged."""
    if not isinstance(prop, str) or not prop:
        msg = "a tolerance is set for a property name, or * for every other property"
        raise InvalidInputError(msg)
    parse(prop, raw, DEFAULTS.get(prop, DEFAULTS["*"]))
    return raw


def read(conn: Connection) -> dict[str, Tolerance]:
    """Defaults updated with the stored settings, in one query."""
    table = dict(DEFAULTS)
    for prop, raw in catalog.settings(conn, SCOPE).items():
        table[prop] = parse(prop, raw, DEFAULTS.get(prop, DEFAULTS["*"]))
    return table


def beyond(tol: Tolerance, new: tuple[Any, ...], held: tuple[Any, ...]) -> bool:
    """Whether ``(value_num, confidence, observability)`` moved beyond ``tol`` from ``held``
    (a number appearing or disappearing always does)."""
    for limit, a, b in zip(tol, new, held, strict=True):
        if a == b:
            continue
        if a is None or b is None or not abs(a - b) <= limit:
            return True
    return False
