"""What a live node does on request, against its world as it is now: the control plane's
commands (set_entity_pose, add_entity, remove_entity) and on-request queries (pointing,
relative positions), each checked first (an unknown entity fails with its id)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

from toaster.errors import InvalidInputError, UnknownEntityError
from toaster.model import shown
from toaster.node import control
from toaster.producers.areas import multiple_relative_position, relative_position
from toaster.producers.monitor import pointing
from toaster.producers.spatial import relative_position_from
from toaster.world.live import LiveSource, check_entity
from toaster.world.state import World


class LiveNode(Protocol):
    """What these requests use of :class:`toaster.node.LiveNode`."""

    world: World
    simu: LiveSource
    store: Any
    config: dict[str, Any]
    _simulated: dict[str, dict[str, Any]]
    _registered: set[str]


def command(node: LiveNode, command: control.Command, t_ns: int) -> None:
    """Apply one control-plane command at ``t_ns``; a one-line error when refused."""
    args, world = command.args, node.world
    if not isinstance(args, dict):
        msg = f"arguments {shown(args)} must be a JSON object"
        raise InvalidInputError(msg)
    entity_id: Any = args.get("id")
    if command.kind == "set_entity_pose":
        row = world.index.get(entity_id) if isinstance(entity_id, str) else None
        if args.get("known_only") and not present(node, entity_id):
            msg = (
                f"unknown entity {shown(entity_id)}: add it first (add_entity) or publish its pose"
            )
            raise UnknownEntityError(msg)
        kind = world.kind_text[row] if row is not None else args.get("kind", "object")
        owner = (
            world.ids[world.owner[row]]
            if row is not None and world.owner[row] >= 0
            else args.get("owner_id", "")
        )
        pose = {
            "position": args.get("position"),
            "rpy": args.get("rpy"),
            "yaw": args.get("yaw", 0.0),
            "kind": kind,
            "owner_id": owner,
            "joint": args.get("joint", ""),
        }
        if not node.simu.push(entity_id, t_ns=t_ns, topic="set_entity_pose", **pose):
            raise InvalidInputError(node.simu.last_error)
        node._simulated[str(entity_id)] = pose
    elif command.kind == "add_entity":
        kind, owner = args.get("kind", "object"), args.get("owner_id", "")
        name = args.get("name", "")
        check_entity(entity_id, kind, owner, name if kind == "joint" else "")
        world.add_entity(
            str(entity_id),
            str(kind),
            owner_id=str(owner),
            name=str(name) if isinstance(name, str) else "",
        )
    elif command.kind == "remove_entity":
        if not (present(node, entity_id) or entity_id in node._registered):
            msg = f"unknown entity {shown(entity_id)}: nothing to remove"
            raise UnknownEntityError(msg)
        eid = str(entity_id)
        row = world.row(eid)
        gone = [eid, *(world.ids[r] for r in range(world.n) if world.owner[r] == row)]
        world.remove_entity(eid)
        for removed in gone:  # its joints go with it
            node._simulated.pop(removed, None)
            if node.store is not None and removed in node._registered:
                node.store.remove_entity(removed)
            node._registered.discard(removed)


def present(node: LiveNode, entity_id: object) -> bool:
    """Whether the world knows the entity now (not removed, not only read back)."""
    row = node.world.index.get(entity_id) if isinstance(entity_id, str) else None
    return row is not None and bool(node.world.active[row])


def require(node: LiveNode, *ids: object) -> None:
    """Fail with "unknown entity" for an id the world does not have now."""
    for entity_id in ids:
        if not present(node, entity_id):
            msg = f"unknown entity {shown(entity_id)}: it is not in the world now"
            raise UnknownEntityError(msg)


def query(node: LiveNode, kind: str, args: Mapping[str, Any]) -> Any:
    """One on-request query (the original's services) against the current world."""
    world = node.world
    if not isinstance(args, Mapping):
        msg = f"arguments {shown(args)} must be a JSON object"
        raise InvalidInputError(msg)
    names = {
        "pointing": ("agent",),
        "get_relative_position": ("subject", "target"),
        "get_multiple_relative_position": ("agent", "object", "target"),
        "relative_position_from": ("viewer", "object"),
    }
    named = [args.get(key) for key in names.get(kind, ())]
    if kind == "relative_position_from" and args.get("reference") is not None:
        named.append(args["reference"])
    require(node, *named)
    if kind == "pointing":
        at = args.get("t_ns")
        config = dict(node.config)  # the request's thresholds, when given
        if args.get("joint_distance"):
            config["pointing_joint_distance"] = float(args["joint_distance"])
        if args.get("angle"):
            config["pointing_angle"] = float(args["angle"])
        found = pointing(
            world,
            str(args["agent"]),
            str(args.get("joint", "rightHand")),
            t_ns=int(at) if at is not None else None,
            config=config,
        )
        return [[entity_id, conf] for entity_id, conf in found]
    if kind == "get_relative_position":
        label, angle = relative_position(world, str(args["subject"]), str(args["target"]))
        return {"direction": label, "angle": angle}
    if kind == "get_multiple_relative_position":
        label, angle = multiple_relative_position(
            world, str(args["agent"]), str(args["object"]), str(args["target"])
        )
        return {"direction": label, "angle": angle}
    if kind == "relative_position_from":
        words, xyz = relative_position_from(
            world,
            str(args["viewer"]),
            str(args["object"]),
            args.get("reference"),
            config=node.config,
        )
        return {"words": words, "forward_left_up": list(xyz)}
    msg = f"unknown query {kind!r}"
    raise ValueError(msg)
