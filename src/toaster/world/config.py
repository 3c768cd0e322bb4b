"""Thresholds as data: the original's defaults, overridable from a dict, YAML file or the store.

Durations are given in seconds (as the original's dynamic-reconfigure file) or as duration
text ("250ms"); they are kept as nanoseconds internally.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from toaster.errors import InvalidInputError
from toaster.model import check_id, check_text, shown
from toaster.timeutil import NS_PER_S, parse_duration

#: The original's effective defaults (agent_monitor cfg, area_manager, pdg); see docs/producers.md.
DEFAULTS: dict[str, Any] = {
    # agent_monitor: attention
    "look_toward_distance": 2.0,
    "look_toward_aperture": 2.0944,
    "head_joint": "head",
    # agent_monitor: body motion
    "body_speed_window": 0.25,
    "body_speed_threshold": 0.12,
    "body_direction_window": 0.5,
    "body_toward_angle": 1.0,
    "body_toward_distance_window": 0.25,
    "body_toward_speed_threshold": 0.12,
    # agent_monitor: joint motion
    "joint_speed_window": 0.25,
    "joint_speed_threshold": 0.12,
    "joint_direction_window": 0.5,
    "joint_toward_angle": 1.0,
    "joint_toward_distance_window": 0.25,
    "joint_toward_speed_threshold": 0.12,
    "motion_max_gap": 1.0,
    # relevance: IsMovingToward only toward targets nearer than this (2D, metres), the upper
    # bound of Distance "far" (dist_far): nobody moves toward something "out" of range
    "toward_range": 8.0,
    # ... and toward a *person* only nearer than this; 0 (default): not toward people. In a
    # crowd person-to-person pairs are nearly all of the intervals, and their growth per hour
    # is many times that of the crowd without them (docs/producers.md, "Relevance")
    "toward_range_humans": 0.0,
    # debounce: a reported state flips only after this much consistent evidence (seconds per
    # property; docs/producers.md). 0.3 s: a standing person with 2 cm noise at 30 Hz no
    # longer flickers between moving and not (docs/producers.md, "Debounce"); a walk start is
    # reported 0.3 s + 1 tick later; samples ≥ 0.3 s apart (ETH/UCY 2.5 Hz) are unaffected
    "min_duration": {"IsMoving": 0.3, "IsFacing": 0.3, "IsMovingToward": 0.3},
    # agent_monitor: Distance labels (upper bounds, metres)
    "dist_reach": 0.05,
    "dist_close": 0.2,
    "dist_medium": 1.5,
    "dist_far": 8.0,
    "distance_emit_out": False,
    # which agents and joints are monitored: "humans" | "robots" | "agents" | list of ids
    "monitored_agents": "humans",
    "monitored_joints": None,
    # toaster run: humans holding beliefs: "none" | "humans" | list of ids (None: per input)
    "belief_holders": None,
    # pointing
    "pointing_joint_distance": 0.3,
    "pointing_angle": 0.5,
    # area_manager
    "facing_angle": 0.5,
    # pdg
    "presence_timeout": 1.0,
    # observabilities (original values) and fixed confidences
    "observability_area": 0.8,
    "observability_facing": 0.5,
    "observability_monitor": 0.0,
    "observability_present": 1.0,
    "observability_in_hand": 0.8,
    # who moved a thing (perception.HandActors): a hand joint within this many metres of an
    # object that moved more than actor_moved metres since the last tick
    "actor_hand_reach": 0.25,
    "actor_moved": 0.05,
    "confidence_present": 0.9,
    "confidence_distance": 0.9,
    # move3d_facts (spatial.py): shapes are boxes standing on their position, x/y centred
    "spatial": False,  # force the spatial producer on (it is on when an entity has a role)
    "on_gap": 0.05,  # IsOn: max height of the object's bottom above the support's top
    "on_penetration": 0.03,  # IsOn: max depth of the bottom below the support's top
    "next_to_distance": 0.3,  # IsNextTo: max gap between footprints (same support / floor)
    "floor_height": 0.05,  # objects whose bottom is this close to z = 0 stand on the floor
    "view_aperture": 2.0944,  # field of view (full cone angle, radians) around the gaze
    "view_range": 8.0,  # metres
    "eye_height": 1.6,  # eyes above an agent's position when it has no head joint
    "visible_min_fraction": 0.2,  # IsVisibleBy when at least this share of points is seen
    "arm_reach": 0.75,  # IsReachableBy: from the shoulder to the nearest point of the box
    "shoulder_height": 1.3,
    "agent_size": [0.5, 0.5, 1.75],  # body box of agents without a size (an occluder)
    "observability_spatial": 1.0,
}

#: The longest duration threshold, in seconds (about 11.6 days).
MAX_SECONDS = 1e6
_SECONDS = {k for k in DEFAULTS if k.endswith("_window")} | {"motion_max_gap", "presence_timeout"}
#: dict-valued settings whose values are durations in seconds, keyed by known names
_SECONDS_BY_NAME = {"min_duration"}


def _seconds(key: str, value: Any) -> float:
    """A non-negative finite number of seconds (duration text accepted), or a one-line error."""
    if isinstance(value, str):
        try:
            value = parse_duration(value) / NS_PER_S
        except InvalidInputError:
            msg = (
                f"invalid value {shown(value)} for {key!r}: give seconds or a duration like '300ms'"
            )
            raise InvalidInputError(msg) from None
    if not _number(value) or not 0 <= value <= MAX_SECONDS:
        msg = (
            f"invalid value {shown(value)} for {key!r}: give a number of seconds from 0 to "
            f"{MAX_SECONDS:g}"
        )
        raise InvalidInputError(msg)
    return float(value)


def _seconds_by_name(key: str, value: Any) -> dict[str, float]:
    """The default mapping updated with ``value`` (known names, durations in seconds)."""
    default = DEFAULTS[key]
    if not isinstance(value, Mapping):
        msg = f"invalid value {shown(value)} for {key!r}: give a mapping such as {default!r}"
        raise InvalidInputError(msg)
    out = dict(default)
    for name, seconds in value.items():
        if name not in default:
            msg = (
                f"unknown property {shown(name)} in {key!r}: use one of "
                f"{', '.join(sorted(default))}"
            )
            raise InvalidInputError(msg)
        out[name] = _seconds(f"{key}.{name}", seconds)
    return out


_CLASSES = ("humans", "robots", "agents")


def _words(key: str, value: Any, example: str) -> list[str]:
    """A list of non-empty texts without NUL, or a one-line error."""
    if not isinstance(value, list | tuple) or not all(
        isinstance(v, str) and v.strip() for v in value
    ):
        msg = f"invalid value {shown(value)} for {key!r}: give a list of ids such as {example}"
        raise InvalidInputError(msg)
    for v in value:
        check_text(v, key)
    return list(value)


def _check_other(key: str, value: Any) -> Any:
    """A setting whose default is not a number: its type checked (one-line errors)."""
    default = DEFAULTS[key]
    if isinstance(default, bool):
        if not isinstance(value, bool):
            msg = f"invalid value {shown(value)} for {key!r}: give true or false"
            raise InvalidInputError(msg)
    elif key == "head_joint":
        check_id(value, key)
    elif key == "monitored_agents":
        if not (isinstance(value, str) and value in _CLASSES):
            _words(key, value, "[humans, BOB, -ANNE]")
    elif key == "monitored_joints":
        if isinstance(value, Mapping):
            for agent, joints in value.items():
                check_id(agent, f"{key} agent")
                _words(f"{key}.{agent}", joints, "[head, rightHand]")
        elif value is not None:
            _words(key, value, "[head, rightHand]")
    elif key == "belief_holders":
        if value is not None and not isinstance(value, str):
            _words(key, value, "[BOB, ANNE]")
        if isinstance(value, str):
            check_text(value, key)
    elif key == "agent_size":
        if (
            not isinstance(value, list | tuple)
            or len(value) != 3
            or not all(_number(v) and 0 < v <= 1e3 for v in value)
        ):
            msg = (
                f"invalid value {shown(value)} for {key!r}: give [x, y, z], positive metres "
                "such as [0.5, 0.5, 1.75]"
            )
            raise InvalidInputError(msg)
        value = [float(v) for v in value]
    return value


def _number(value: Any) -> bool:
    """True for a finite int or float (not a bool; ints of any size)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def make_config(overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The defaults updated with ``overrides``; unknown keys and bad values raise one line."""
    if overrides is not None and not isinstance(overrides, Mapping):
        msg = (
            f"invalid thresholds {shown(overrides)}: give a mapping such as "
            "{toward_range_humans: 3.6}"
        )
        raise InvalidInputError(msg)
    config = dict(DEFAULTS)
    config.update({key: dict(DEFAULTS[key]) for key in _SECONDS_BY_NAME})  # no shared dicts
    for key, value in (overrides or {}).items():
        if key not in DEFAULTS:
            msg = f"unknown threshold {shown(key)}: known ones are listed in docs/producers.md"
            raise InvalidInputError(msg)
        default = DEFAULTS[key]
        if key in _SECONDS_BY_NAME:
            value = _seconds_by_name(key, value)
        elif key in _SECONDS:
            value = _seconds(key, value)
        elif isinstance(default, float):
            if not _number(value) or value < 0:
                msg = f"invalid value {shown(value)} for {key!r}: give a non-negative number"
                raise InvalidInputError(msg)
            value = float(value)
        else:
            value = _check_other(key, value)
        config[key] = value
    return config


def read_config_file(path: str | Path) -> dict[str, Any]:
    """Producer thresholds from a YAML/JSON mapping file, validated (one-line errors)."""
    from toaster.documents import read_document

    overrides = read_document(path, "config")
    if not isinstance(overrides, dict):
        msg = (
            f"config {str(path)!r} must be a mapping of thresholds such as "
            "'toward_range_humans: 3.6'"
        )
        raise InvalidInputError(msg)
    try:
        make_config(overrides)
    except InvalidInputError as exc:
        msg = f"config {str(path)!r}: {exc}"
        raise InvalidInputError(msg) from None
    return overrides


def overlay_config(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` (a file's config) with ``over`` laid on it; dict-valued settings such as
    ``min_duration`` are merged name by name."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = {**out[key], **value}
        else:
            out[key] = value
    return out


def ns(config: Mapping[str, Any], key: str, name: str | None = None) -> int:
    """A duration threshold in nanoseconds (``name``: an entry of a dict-valued setting)."""
    value = config[key] if name is None else config[key][name]
    return round(float(value) * NS_PER_S)
