"""toaster_msgs/Fact fields of facts, filled as the original's nodes fill them.

The original's value fields follow a convention per fact kind (reference §2.0; pdg, area_manager,
agent_monitor and move3d_facts sources): ``valueType`` 1 only where the number *is* the value
(IsLookingToward / IsLookingAt / IsFacing / AreaDensity, with ``stringValue`` left empty),
0 elsewhere; IsMovingToward leaves ``stringValue`` empty; IsMoving and Distance carry their
text and a number beside it. :data:`ORIGINAL_VALUES` is that table; a property it does not name
(a user's own) gets valueType 1 exactly when it has a number. :func:`fact_from_msg` inverts
:func:`fact_fields`, so a toaster fact comes back equal through a message.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from toaster.model import Fact


class ValueFields(NamedTuple):
    """How a fact kind fills toaster_msgs/Fact: ``valueType``, whether ``stringValue`` carries
    the fact's text (else ""), whether ``doubleValue`` carries its number."""

    value_type: bool
    text: bool
    number: bool


_NUMBER = ValueFields(True, False, True)  # the number is the value
_TEXT = ValueFields(False, True, False)  # "true" (or a label) and nothing else
_BOTH = ValueFields(False, True, True)  # a text, and a number beside it
#: The original's value fields per property (toaster's own spatial facts follow move3d_facts's).
ORIGINAL_VALUES: dict[str, ValueFields] = {
    # pdg
    "isPresent": _TEXT,
    "IsInHand": _TEXT,
    # area_manager
    "IsInRoom": _TEXT,
    "IsAt": _TEXT,
    "IsInArea": _TEXT,
    "IsFacing": _NUMBER,
    "AreaDensity": _NUMBER,
    # agent_monitor
    "IsLookingToward": _NUMBER,
    "IsLookingAt": _NUMBER,
    "IsMoving": _BOTH,
    "IsMovingToward": ValueFields(False, False, True),
    "Distance": _BOTH,
    # move3d_facts: valueType never set, "true"/"false", the numeric value beside it
    "IsIn": _TEXT,
    "IsOn": _TEXT,
    "IsClosed": _TEXT,
    "IsNextTo": _BOTH,
    "IsVisibleBy": _BOTH,
    "CanSee": _BOTH,
    "IsReachableBy": _BOTH,
    "CanReach": _BOTH,
}


def fact_fields(fact: Fact, t_ns: int) -> dict[str, Any]:
    """toaster_msgs/Fact fields of a fact held at ``t_ns``, value fields as the original's
    (:data:`ORIGINAL_VALUES`)."""
    num = fact.value_num
    kind = ORIGINAL_VALUES.get(fact.property)
    if kind is None:
        kind = ValueFields(num is not None, True, True)
    return {
        "property": fact.property,
        "propertyType": fact.property_type,
        "subProperty": fact.sub_property,
        "subjectId": fact.subject_id,
        "targetId": fact.target_id,
        "subjectOwnerId": fact.subject_owner_id,
        "targetOwnerId": fact.target_owner_id,
        "valueType": kind.value_type,
        "factObservability": float(fact.observability),
        "doubleValue": float(num) if num is not None and kind.number else 0.0,
        "stringValue": fact.value_text if kind.text else "",
        "confidence": float(fact.confidence),
        "time": t_ns,
        "timeStart": t_ns,
        "timeEnd": 0,
    }


def fact_from_msg(msg: Any) -> Fact:
    """A toaster Fact from a toaster_msgs/Fact (or Event): a number when valueType is 1 or the
    kind carries one (:data:`ORIGINAL_VALUES`); an empty string value means "true"."""
    prop = str(msg.property)
    kind = ORIGINAL_VALUES.get(prop)
    number = bool(msg.valueType) or (kind is not None and kind.number)
    return Fact(
        str(msg.subjectId),
        prop,
        str(msg.targetId),
        str(msg.stringValue) or "true",
        float(msg.doubleValue) if number else None,
        float(msg.confidence),
        float(msg.factObservability),
        str(msg.propertyType),
        str(msg.subProperty),
        str(msg.subjectOwnerId),
        str(msg.targetOwnerId),
    )
