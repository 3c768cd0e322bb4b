"""``toaster serve``: a live node beside a robot (the loop lives in :mod:`toaster.node`)."""

from __future__ import annotations

import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from toaster.cli.publish import check_publish, publish_options, published
from toaster.cli.rosopts import pose_topics as parse_pose_topics
from toaster.cli.rosopts import ros_input_options
from toaster.errors import InvalidInputError

if TYPE_CHECKING:
    from toaster.db.database import Database


DEFAULT_SELF = "toaster"


def self_agent_of(db: Database, requested: str | None) -> str:
    """The node's self agent: ``requested``, else the database's one self agent, else
    ``toaster``. A second self agent would break every command that defaults to the self
    agent, so another id than the one the database has is refused."""
    selves = sorted(agent for agent, is_self in db.store().agents().items() if is_self)
    if requested is None:
        if len(selves) > 1:
            msg = f"the database has several self agents ({', '.join(selves)}): give --self ID"
            raise InvalidInputError(msg)
        return selves[0] if selves else DEFAULT_SELF
    if selves and requested not in selves:
        msg = (
            f"--self {requested!r}: the database's self agent is {', '.join(selves)}; leave "
            "--self out to use it (two self agents break the commands that default to it)"
        )
        raise InvalidInputError(msg)
    return requested


@click.command("serve")
@click.option(
    "--rate",
    type=float,
    default=30.0,
    show_default=True,
    help="Ticks per second (the original's nodes run at 30 Hz).",
)
@click.option(
    "--config",
    "config_file",
    metavar="FILE",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Producer thresholds (YAML/JSON mapping).",
)
@click.option(
    "--self",
    "self_id",
    default=None,
    metavar="ID",
    help="The robot whose perception the world state is (default: the database's self "
    "agent, else toaster).",
)
@click.option(
    "--holders",
    default="none",
    show_default=True,
    metavar="none|humans|ID[,ID...]",
    help="Humans that hold beliefs (store agents).",
)
@click.option(
    "--seconds",
    type=float,
    default=None,
    help="Stop after this many seconds (default: until SIGINT/SIGTERM).",
)
@click.option(
    "--status-every",
    "status_every",
    type=float,
    default=10.0,
    show_default=True,
    metavar="S",
    help="Log a status line every S seconds (uptime, ticks, overruns, "
    "dropped inputs, warnings, tick times since the last line); with --ros1 also "
    "on /toaster/status. 0: none.",
)
@click.option(
    "--stamp",
    type=click.Choice(["perception", "wall"]),  # toaster.node.stamps.STAMP_MODES
    default="perception",
    show_default=True,
    help="A tick's time, hence its facts': the newest pose stamp it applies (if not older "
    "than the node's max_stamp_lag, else the wall clock; docs/time.md), or the wall clock.",
)
@publish_options(
    "Bridge to ROS 1 (needs Debian's ROS 1 packages; see docs/ros1.md).",
    "Bridge to ROS 2 over DDS, no ROS 2 install needed (toaster[ros2]; docs/ros2.md).",
)
@ros_input_options
@click.pass_obj
def serve(
    app: Any,
    rate: float,
    config_file: Path | None,
    self_id: str | None,
    holders: str,
    seconds: float | None,
    status_every: float,
    stamp: str,
    ros1: bool,
    ros2: bool,
    domain_id: int | None,
    foxglove: int | None,
    tf_map: Path | None,
    pose_topics: tuple[str, ...],
) -> None:
    """Run toaster live: poses in, facts and beliefs stored and published every tick.

    Change it while it runs from another shell: `toaster area add`, `toaster monitor`,
    `toaster stream`, `toaster hand`, `toaster entity`; ask it `toaster pointing` and
    `toaster relative-position`. Stops cleanly on Ctrl-C or SIGTERM (the last tick is stored
    whole or not at all); started again on the same database, it carries on.
    """
    from toaster.node import LiveNode
    from toaster.node import serve as serve_node
    from toaster.timeutil import check_rate, check_seconds

    rate = check_rate(rate, "--rate")
    status_every = check_seconds(status_every, "--status-every")
    if seconds is not None and seconds < 0:
        msg = f"--seconds {seconds:g} must not be negative"
        raise InvalidInputError(msg)
    if (tf_map is not None or pose_topics) and not (ros1 or ros2):
        msg = "--tf-map and --pose-topic are ROS inputs: add --ros1 or --ros2"
        raise InvalidInputError(msg)
    check_publish(ros2=ros2, domain_id=domain_id)
    from toaster.world.config import read_config_file

    config = read_config_file(config_file) if config_file is not None else None
    topics = parse_pose_topics(pose_topics)
    choice: str | list[str] = holders
    if holders not in ("none", "humans"):
        choice = [h.strip() for h in holders.split(",") if h.strip()]
    logging.basicConfig(
        stream=sys.stderr, level=logging.WARNING, format="toaster serve: %(message)s"
    )
    # status lines at INFO on a handler of their own (rospy's set-up raises the root's level)
    status = logging.getLogger("toaster.node.status")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("toaster serve: %(message)s"))
    status.addHandler(handler)
    status.setLevel(logging.INFO)
    status.propagate = False
    self_id = self_agent_of(app.db, self_id)
    node = LiveNode(app.db, config=config, self_id=self_id, holders=choice, stamp=stamp)
    outputs = published(
        node,
        "toaster serve",
        ros1=ros1,
        ros2=ros2,
        domain_id=domain_id,
        foxglove=foxglove,
        tf_map=tf_map,
        pose_topics=topics,
    )
    with outputs:
        click.echo(f"toaster serve: {rate:g} Hz on {app.db.url} (Ctrl-C stops)", err=True)
        stats = serve_node(node, rate, seconds=seconds, status_every_s=status_every)
    p50 = sorted(stats.tick_ms)[len(stats.tick_ms) // 2] if stats.tick_ms else 0.0
    click.echo(
        f"toaster serve: stopped after {stats.ticks} ticks ({stats.overruns} overran "
        f"{1e3 / rate:.1f} ms; median {p50:.1f} ms, worst {stats.worst_ms:.1f} ms); "
        f"{stats.commands} commands, {stats.warnings} warnings; dropped "
        f"{node.drops.summary()}",
        err=True,
    )
    faults = node.faults.summary()  # only when something failed (docs/live.md, "Faults")
    if faults:
        click.echo(f"toaster serve: {faults}", err=True)
