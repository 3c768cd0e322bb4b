"""Control a running node (or the next one) through the database: monitored agents, streams,
held objects, entities, and on-request queries (:mod:`toaster.node.control`)."""

from __future__ import annotations

import json
from typing import Any

import click

from toaster.cli.output import emit, listing_options
from toaster.errors import InvalidInputError

_WAIT = click.option(
    "--timeout",
    type=float,
    default=2.0,
    show_default=True,
    help="Seconds to wait for the running node's answer.",
)


def _show_monitor(state: Any) -> None:
    agents = (
        "(producers' default: humans)"
        if state.agents is None
        else (", ".join(state.agents) or "(nobody)")
    )
    click.echo(f"monitored agents: {agents}")
    if state.excluded:
        click.echo(f"except: {', '.join(state.excluded)}")
    if state.joints:
        for agent, joints in sorted(state.joints.items()):
            click.echo(f"joints of {agent}: {', '.join(joints) or '(none)'}")


@click.group("monitor")
def monitor() -> None:
    """Which agents (and joints) agent_monitor computes motion and attention for."""


@monitor.command("add")
@click.argument("agent")
@click.option("--joint", "joints", multiple=True, help="Monitor this joint of it (repeatable).")
@click.pass_obj
def monitor_add(app: Any, agent: str, joints: tuple[str, ...]) -> None:
    """Monitor AGENT (add_agent; --joint: add_joint_to_agent)."""
    from toaster.node import control

    _show_monitor(control.monitor_add(app.db, agent, joints))


@monitor.command("remove")
@click.argument("agent")
@click.option("--joint", default=None, help="Only stop monitoring this joint of it.")
@click.pass_obj
def monitor_remove(app: Any, agent: str, joint: str | None) -> None:
    """Stop monitoring AGENT (remove_agent) or one of its joints (remove_joint_to_agent)."""
    from toaster.node import control

    _show_monitor(control.monitor_remove(app.db, agent, joint))


@monitor.command("all")
@click.argument("which", type=click.Choice(["humans", "robots", "agents"]))
@click.option("--off", is_flag=True, help="Stop monitoring that class instead.")
@click.pass_obj
def monitor_all(app: Any, which: str, off: bool) -> None:
    """Monitor every human / robot / agent, also those that appear later (monitor_all_*)."""
    from toaster.node import control

    _show_monitor(control.monitor_all(app.db, which, on=not off))


@monitor.command("clear")
@click.option(
    "--joints",
    "joints_only",
    is_flag=True,
    help="Only forget joint choices (remove_all_joints_to_agent).",
)
@click.pass_obj
def monitor_clear(app: Any, joints_only: bool) -> None:
    """Monitor nobody (remove_all_agents)."""
    from toaster.node import control

    _show_monitor(control.monitor_clear(app.db, joints_only))


@monitor.command("list")
@click.pass_obj
def monitor_list(app: Any) -> None:
    """Show what is monitored."""
    from toaster.node import control

    with app.db.transaction() as conn:
        _show_monitor(control.read_state(conn))


@click.command("stream")
@click.argument("name", required=False)
@click.argument("state", required=False, type=click.Choice(["on", "off"]))
@listing_options
@click.pass_obj
def stream(
    app: Any, name: str | None, state: str | None, fmt: str | None, limit: int | None
) -> None:
    """Switch input stream NAME on or off (manage_stream); no arguments: list them."""
    from toaster.node import control

    if name is None or state is None:
        if name is not None:
            msg = f"say whether stream {name!r} is on or off: toaster stream {name} on|off"
            raise InvalidInputError(msg)
        with app.db.transaction() as conn:
            streams = control.read_state(conn).streams
        rows = [(key, "on" if on else "off") for key, on in sorted(streams.items())]
        emit(rows, fmt, columns=["stream", "state"], limit=limit, empty="(every stream on)")
        return
    control.set_stream(app.db, name, state == "on")
    click.echo(f"stream {name} {state}")


@click.group("hand")
def hand() -> None:
    """Objects held in an agent's hand (put_in_hand / remove_from_hand)."""


@hand.command("put")
@click.argument("object_id", metavar="OBJECT")
@click.argument("agent")
@click.option("--joint", default="rightHand", show_default=True, help="The hand joint.")
@click.pass_obj
def hand_put(app: Any, object_id: str, agent: str, joint: str) -> None:
    """OBJECT follows AGENT's hand joint until removed."""
    from toaster.node import control

    control.put_in_hand(app.db, object_id, agent, joint)
    click.echo(f"{object_id} in {agent}'s {joint}")


@hand.command("remove")
@click.argument("object_id", metavar="OBJECT")
@click.pass_obj
def hand_remove(app: Any, object_id: str) -> None:
    """Release OBJECT; it stays where it last was."""
    from toaster.node import control

    with app.db.transaction() as conn:  # checked first: a failed command writes nothing
        held = object_id in control.read_state(conn).in_hand
    if not held or not control.remove_from_hand(app.db, object_id):
        msg = f'{object_id!r} is in no hand: see `toaster execute "SELECT * FROM settings"`'
        raise InvalidInputError(msg)
    click.echo(f"{object_id} released")


@click.group("entity")
def entity() -> None:
    """Add, remove and place entities of a running node (toaster_simu)."""


@entity.command("pose")
@click.argument("entity_id", metavar="ID")
@click.argument("position", nargs=-1, type=float, required=True)
@click.option("--yaw", type=float, default=0.0, help="Heading in radians.")
@click.option(
    "--quat",
    type=float,
    nargs=4,
    default=None,
    metavar="X Y Z W",
    help="Orientation as a quaternion (instead of --yaw).",
)
@click.option(
    "--kind",
    default="object",
    show_default=True,
    type=click.Choice(["human", "robot", "object"]),
    help="Kind, if it is new.",
)
@click.pass_obj
def entity_pose(
    app: Any,
    entity_id: str,
    position: tuple[float, ...],
    yaw: float,
    quat: tuple[float, float, float, float] | None,
    kind: str,
) -> None:
    """Set ID's pose to X Y [Z] (set_entity_pose); applied by the running node or the next."""
    from toaster.model import MAX_COORD
    from toaster.node import control
    from toaster.world.live import quaternion_to_rpy

    if len(position) not in (2, 3):
        msg = f"give X Y or X Y Z for {entity_id!r}, not {len(position)} numbers"
        raise InvalidInputError(msg)
    if any(abs(v) > MAX_COORD for v in (*position, yaw, *(quat or ()))):
        msg = f"the pose of {entity_id!r} must lie within ±{MAX_COORD:g} m (and radians)"
        raise InvalidInputError(msg)
    args: dict[str, Any] = {"id": entity_id, "position": list(position), "yaw": yaw, "kind": kind}
    if quat is not None:
        try:
            args["rpy"] = list(quaternion_to_rpy(*quat))
        except ValueError as exc:
            raise InvalidInputError(str(exc)) from None
    control.submit(app.db, "set_entity_pose", args)
    click.echo(f"pose of {entity_id} sent")


@entity.command("add")
@click.argument("entity_id", metavar="ID")
@click.option(
    "--kind",
    default="object",
    show_default=True,
    type=click.Choice(["human", "robot", "object", "joint"]),
)
@click.option("--owner", default="", help="The agent of a joint.")
@click.pass_obj
def entity_add(app: Any, entity_id: str, kind: str, owner: str) -> None:
    """Add entity ID to the running node (add_entity)."""
    from toaster.node import control

    control.submit(app.db, "add_entity", {"id": entity_id, "kind": kind, "owner_id": owner})
    click.echo(f"entity {entity_id} sent")


@entity.command("remove")
@click.argument("entity_id", metavar="ID")
@click.pass_obj
def entity_remove(app: Any, entity_id: str) -> None:
    """Remove entity ID (remove_entity)."""
    from toaster.node import control

    control.submit(app.db, "remove_entity", {"id": entity_id})
    click.echo(f"removal of {entity_id} sent")


@click.command("pointing")
@click.argument("agent")
@click.option("--joint", default="rightHand", show_default=True, help="The pointing joint.")
@click.option(
    "--ago",
    default=None,
    metavar="T",
    help="As the agent pointed this long ago (pointing_time), e.g. 500ms.",
)
@_WAIT
@click.pass_obj
def pointing_cmd(app: Any, agent: str, joint: str, ago: str | None, timeout: float) -> None:
    """What AGENT points at, best first (asks the running node)."""
    from toaster.cli.checks import parse_duration_option
    from toaster.node import control
    from toaster.timeutil import check_ns, now_ns

    args: dict[str, Any] = {"agent": agent, "joint": joint}
    if ago is not None:
        args["t_ns"] = check_ns(
            now_ns() - parse_duration_option(ago, "--ago"), f"--ago {ago!r}: the time"
        )
    answer = control.ask(app.db, "pointing", args, timeout)
    for entity_id, confidence in answer:
        click.echo(f"{entity_id}\t{confidence:.3f}")
    if not answer:
        click.echo(f"{agent} points at nothing")


@click.command("relative-position")
@click.argument("subject")
@click.argument("target")
@click.option(
    "--from",
    "viewer",
    default=None,
    help="Seen from this agent: where TARGET is relative to SUBJECT "
    "(get_multiple_relative_position).",
)
@_WAIT
@click.pass_obj
def relative_position(
    app: Any, subject: str, target: str, viewer: str | None, timeout: float
) -> None:
    """Where TARGET is for SUBJECT: front, left, back, right (asks the running node)."""
    from toaster.node import control

    if viewer is None:
        answer = control.ask(
            app.db, "get_relative_position", {"subject": subject, "target": target}, timeout
        )
    else:
        answer = control.ask(
            app.db,
            "get_multiple_relative_position",
            {"agent": viewer, "object": subject, "target": target},
            timeout,
        )
    click.echo(json.dumps(answer))
