"""The ROS input options shared by ``toaster serve --ros1`` and ``toaster run BAG``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from toaster.errors import InvalidInputError


def ros_input_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--tf-map FILE`` and ``--pose-topic TOPIC=ID[:KIND]`` (repeatable)."""
    func = click.option(
        "--pose-topic",
        "pose_topics",
        multiple=True,
        metavar="TOPIC=ID[:KIND]",
        help="A geometry_msgs/PoseStamped topic giving one entity's pose "
        "(repeatable; KIND human, robot or object, default object).",
    )(func)
    func = click.option(
        "--tf-map",
        "tf_map",
        metavar="FILE",
        type=click.Path(exists=True, dir_okay=False, path_type=Path),
        help="Which /tf frames are which entities and joints (YAML/JSON; docs/ros1.md).",
    )(func)
    return func


def pose_topics(values: tuple[str, ...]) -> dict[str, tuple[str, str]]:
    """``TOPIC=ID[:KIND]`` options as {topic: (entity id, kind)}."""
    out: dict[str, tuple[str, str]] = {}
    for value in values:
        topic, sep, target = value.partition("=")
        entity_id, _, kind = target.partition(":")
        kind = kind or "object"
        if not sep or not topic or not entity_id or kind not in ("human", "robot", "object"):
            msg = (
                f"--pose-topic {value!r}: give TOPIC=ID or TOPIC=ID:KIND (human, robot or "
                "object), e.g. /mocap/bob=bob:human"
            )
            raise InvalidInputError(msg)
        out[topic] = (entity_id, kind)
    return out
