"""The live outputs shared by ``toaster serve`` and ``toaster run``: the options ``--ros1``,
``--ros2``, ``--domain-id`` and ``--foxglove [PORT]``, and :func:`published`, which starts the
outputs on a node (a :class:`~toaster.node.LiveNode`, or a run's
:class:`~toaster.app.published.RunNode`) and stops them. Their packages are imported only
when asked for (``toaster --help`` stays fast); ``cli/extras.py`` checks the extras first."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import click

from toaster.errors import InvalidInputError


def publish_options(
    ros1_help: str, ros2_help: str
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Add ``--ros1``, ``--ros2`` (their help as given), ``--domain-id N`` and ``--foxglove
    [PORT]``."""

    def add(func: Callable[..., Any]) -> Callable[..., Any]:
        func = click.option(
            "--foxglove",
            type=click.IntRange(0, 65535),
            is_flag=False,
            flag_value=8765,
            default=None,
            metavar="[PORT]",
            help="Serve the Foxglove app on ws://127.0.0.1:PORT (default 8765; 0: a free "
            "port, printed); needs toaster[foxglove] (docs/foxglove.md).",
        )(func)
        func = click.option(
            "--domain-id",
            "domain_id",
            type=int,
            default=None,
            metavar="N",
            help="ROS 2 domain (default: ROS_DOMAIN_ID, else 0).",
        )(func)
        func = click.option("--ros2", is_flag=True, help=ros2_help)(func)
        return click.option("--ros1", is_flag=True, help=ros1_help)(func)

    return add


def check_publish(*, ros2: bool, domain_id: int | None) -> None:
    """Refuse ``--domain-id`` without ``--ros2``."""
    if not ros2 and domain_id is not None:
        msg = "--domain-id is a ROS 2 option: add --ros2"
        raise InvalidInputError(msg)


@contextmanager
def published(
    node: Any,
    who: str,
    *,
    run: bool = False,
    ros1: bool = False,
    ros2: bool = False,
    domain_id: int | None = None,
    foxglove: int | None = None,
    tf_map: Path | None = None,
    pose_topics: Mapping[str, tuple[str, str]] | None = None,
) -> Iterator[None]:
    """Start the asked outputs on ``node`` (``who`` prefixes the lines printed: the Foxglove
    port), stopped when the context ends. With ``run`` (a run's
    :class:`~toaster.app.published.RunNode`) they offer no service that changes a live node
    and read no input beyond /tf, tell the node who listens and follow its clock
    (docs/foxglove.md, docs/ros2.md)."""
    with ExitStack() as stack:
        reduced: dict[str, Any] = (
            {"services": False, "toaster_simu": False, "ros4hri": False} if run else {}
        )
        if ros1:
            from toaster.ros1.bridge import start_bridge

            bridge = start_bridge(node, tf_map=tf_map, pose_topics=pose_topics, **reduced)
            stack.callback(bridge.shutdown)
            if run:
                node.clocks.append(bridge.clock())
                node.listeners.append(bridge.listened)
        if ros2:
            from toaster.ros2.bridge import start_bridge as start_ros2

            bridge2 = start_ros2(
                node, domain_id=domain_id, tf_map=tf_map, pose_topics=pose_topics, **reduced
            )
            stack.callback(bridge2.shutdown)
            if run:
                node.clocks.append(bridge2.clock())
                node.listeners.append(bridge2.listened)
        if foxglove is not None:
            from toaster.foxglove.server import start_server

            fox = start_server(node, foxglove, services=not run, clock=run)
            stack.callback(fox.shutdown)
            if run:
                node.clocks.append(fox.server.broadcast_time)
                node.listeners.append(fox.channels.listened)
            click.echo(f"{who}: Foxglove on ws://127.0.0.1:{fox.port}", err=True)
        yield
