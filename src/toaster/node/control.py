"""The control plane of a running node, kept as data in the database (revision 0005).

Everything a running node (``toaster serve``) must apply lives in the database, so that the
``toaster`` CLI, a ROS service or a SQL script can change it, from any process, with or without
a node running (a node reads it at start-up and again whenever it changed):

* areas: the ``areas`` table (:meth:`toaster.db.Store.put_area`);
* monitored agents and joints: setting ``monitor.agents`` (classes ``humans`` / ``robots`` /
  ``agents`` and ids), ``monitor.except`` (ids removed from a class) and ``monitor.joints``
  ({agent: [joint names]}; absent: every joint of a monitored agent);
* streams on/off (the original's ``manage_stream``): scope ``streams``, one boolean per source;
* objects in a hand (``put_in_hand`` / ``remove_from_hand``): scope ``in_hand``,
  object -> {"agent", "joint"};
* one-shot commands (``set_entity_pose``, ``add_entity``, ``remove_entity``) and on-request
  queries (``pointing``, ``get_relative_position``, ...): rows of ``control_commands`` that
  the node answers within a tick. Commands wait for the next node; a query nobody answered in
  time is withdrawn.

Every change bumps ``store_state.control_version`` in its own write transaction (SQLite: BEGIN
IMMEDIATE, so a change that reads before it writes never meets a busy node half-way); the node
compares
that number once per tick (PostgreSQL also gets ``NOTIFY toaster_control``). Choice written
down: ``monitor all humans`` is kept as the class, so humans that appear later are monitored
too (the original added only those present at that moment, which surprised its users).
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from sqlalchemy import Connection, text

from toaster.db import catalog
from toaster.errors import InvalidInputError, ToasterError
from toaster.model import check_id
from toaster.timeutil import now_ns
from toaster.world.config import DEFAULTS

if TYPE_CHECKING:
    from toaster.db.database import Database

MONITOR, STREAMS, IN_HAND = "monitor", "streams", "in_hand"
CLASSES = ("humans", "robots", "agents")
DEFAULT_MONITORED = DEFAULTS["monitored_agents"]  # what a node monitors until told otherwise
#: kinds of one-shot commands the node applies, and of queries it answers
COMMANDS = ("set_entity_pose", "add_entity", "remove_entity")
QUERIES = (
    "pointing",
    "get_relative_position",
    "get_multiple_relative_position",
    "relative_position_from",
)


class NoNodeError(ToasterError):
    """No running node answered a query in time."""


# -- state ------------------------------------------------------------------------------------
@dataclass
class ControlState:
    """What the node applies: monitored agents, streams, held objects (areas are read apart)."""

    agents: list[str] | None = None  # None: the producers' config decides
    excluded: list[str] = field(default_factory=list)
    joints: dict[str, list[str]] | None = None
    streams: dict[str, bool] = field(default_factory=dict)
    in_hand: dict[str, tuple[str, str]] = field(default_factory=dict)

    def monitored_agents(self, default: object) -> object:
        """The AgentMonitor ``monitored_agents`` value: stored choice, else ``default``."""
        return default if self.agents is None else list(self.agents)


def _agents(state: ControlState) -> list[str]:
    """The stored choice, or the producers' default (every human) when none was made."""
    return list(state.agents) if state.agents is not None else [DEFAULT_MONITORED]


def read_state(conn: Connection) -> ControlState:
    """The stored control state."""
    monitor = catalog.settings(conn, MONITOR)
    hands = {
        obj: (v["agent"], v["joint"])
        for obj, v in catalog.settings(conn, IN_HAND).items()
        if isinstance(v, dict) and _texts(v.get("agent"), v.get("joint"))
    }
    agents = monitor.get("agents")
    joints = monitor.get("joints")
    if isinstance(joints, dict):
        joints = {a: list(j) for a, j in joints.items() if isinstance(j, list) and _texts(*j)}
    return ControlState(
        agents=list(agents) if isinstance(agents, list) and _texts(*agents) else None,
        excluded=list(monitor.get("except", [])) if _text_list(monitor.get("except", [])) else [],
        joints=joints if isinstance(joints, dict) else None,
        streams={k: bool(v) for k, v in catalog.settings(conn, STREAMS).items()},
        in_hand=hands,
    )


def _texts(*values: object) -> bool:
    return all(isinstance(v, str) for v in values)


def _text_list(value: object) -> bool:
    """Whether a stored setting is a list of texts (anything else, written by hand with SQL,
    is ignored as absent)."""
    return isinstance(value, list) and _texts(*value)


# -- monitored agents (agent_monitor services) ---------------------------------------------------
def monitor_add(db: Database, agent_id: str, joints: Sequence[str] = ()) -> ControlState:
    """Monitor an agent (``add_agent``), optionally naming joints (``add_joint_to_agent``)."""
    check_id(agent_id, "agent id")
    with db.transaction(write=True) as conn:
        state = read_state(conn)
        agents = [a for a in _agents(state) if a != agent_id] + [agent_id]
        catalog.put_setting(conn, MONITOR, "agents", agents)
        catalog.put_setting(conn, MONITOR, "except", [a for a in state.excluded if a != agent_id])
        if joints:
            table = dict(state.joints or {})
            table[agent_id] = sorted({*table.get(agent_id, []), *joints})
            catalog.put_setting(conn, MONITOR, "joints", table)
        catalog.bump_control(conn)
        return read_state(conn)


def monitor_remove(db: Database, agent_id: str, joint: str | None = None) -> ControlState:
    """Stop monitoring an agent (``remove_agent``) or one of its joints
    (``remove_joint_to_agent``)."""
    with db.transaction(write=True) as conn:
        state = read_state(conn)
        if joint is not None:
            table = dict(state.joints or {})
            if joint not in table.get(agent_id, []):
                msg = (
                    f"joint {joint!r} of {agent_id!r} is not monitored: see 'toaster monitor list'"
                )
                raise InvalidInputError(msg)
            table[agent_id] = [j for j in table[agent_id] if j != joint]
            catalog.put_setting(conn, MONITOR, "joints", table)
        else:
            agents = [a for a in _agents(state) if a != agent_id]
            catalog.put_setting(conn, MONITOR, "agents", agents)
            if any(a in CLASSES for a in agents):
                catalog.put_setting(conn, MONITOR, "except", sorted({*state.excluded, agent_id}))
        catalog.bump_control(conn)
        return read_state(conn)


def monitor_all(db: Database, which: str, on: bool = True) -> ControlState:
    """Monitor every human / robot / agent, now and later (``monitor_all_*``); ``on=False``
    stops monitoring that class (ids added one by one stay)."""
    if which not in CLASSES:
        msg = f"cannot monitor all {which!r}: use one of {', '.join(CLASSES)}"
        raise InvalidInputError(msg)
    with db.transaction(write=True) as conn:
        state = read_state(conn)
        agents = [a for a in _agents(state) if a != which] + ([which] if on else [])
        catalog.put_setting(conn, MONITOR, "agents", agents)
        if on:
            catalog.put_setting(conn, MONITOR, "except", [])
        catalog.bump_control(conn)
        return read_state(conn)


def monitor_clear(db: Database, joints_only: bool = False) -> ControlState:
    """Monitor nobody (``remove_all_agents``), or only forget joint choices
    (``remove_all_joints_to_agent``: every joint of a monitored agent again)."""
    with db.transaction(write=True) as conn:
        if joints_only:
            catalog.delete_setting(conn, MONITOR, "joints")
        else:
            catalog.put_setting(conn, MONITOR, "agents", [])
            catalog.put_setting(conn, MONITOR, "except", [])
            catalog.delete_setting(conn, MONITOR, "joints")
        catalog.bump_control(conn)
        return read_state(conn)


# -- streams, hands ------------------------------------------------------------------------------
def set_stream(db: Database, name: str, on: bool) -> None:
    """Switch an input stream on or off (``manage_stream``)."""
    check_id(name, "stream name")
    with db.transaction(write=True) as conn:
        catalog.put_setting(conn, STREAMS, name, bool(on))
        catalog.bump_control(conn)


def put_in_hand(db: Database, object_id: str, agent_id: str, joint: str) -> None:
    """An object follows an agent's joint until removed (``put_in_hand``)."""
    for value, what in ((object_id, "object id"), (agent_id, "agent id"), (joint, "joint")):
        check_id(value, what)
    with db.transaction(write=True) as conn:
        catalog.put_setting(conn, IN_HAND, object_id, {"agent": agent_id, "joint": joint})
        catalog.bump_control(conn)


def remove_from_hand(db: Database, object_id: str) -> bool:
    """Release an object (``remove_from_hand``); False if it was in no hand."""
    with db.transaction(write=True) as conn:
        found = catalog.delete_setting(conn, IN_HAND, object_id) > 0
        if found:  # nothing changed otherwise: the node has nothing to re-read
            catalog.bump_control(conn)
        return found


# -- commands and queries ------------------------------------------------------------------------
@dataclass
class Command:
    """One pending row of ``control_commands``."""

    id: int
    kind: str
    args: Any  # a dict when well-formed; the node refuses anything else


def submit(db: Database, kind: str, args: Mapping[str, Any]) -> int:
    """Queue a command or query for the node; return its id."""
    if kind not in COMMANDS + QUERIES:
        msg = f"unknown control command {kind!r}: use one of {', '.join(COMMANDS + QUERIES)}"
        raise InvalidInputError(msg)
    with db.transaction(write=True) as conn:
        new_id = conn.execute(
            text(
                "INSERT INTO control_commands (kind, args_json, created_ns, state) "
                "VALUES (:kind, :args, :t, 'pending') RETURNING id"
            ),
            {"kind": kind, "args": json.dumps(dict(args)), "t": now_ns()},
        ).scalar_one()
        catalog.bump_control(conn)
        return int(new_id)


def ask(db: Database, kind: str, args: Mapping[str, Any], timeout_s: float = 2.0) -> Any:
    """Submit a query and wait for the node's answer; withdraw it if none came in time."""
    command_id = submit(db, kind, args)
    deadline = time.monotonic() + timeout_s
    while True:
        with db.transaction() as conn:  # a read while waiting
            row = conn.execute(
                text("SELECT state, answer_json FROM control_commands WHERE id = :id"),
                {"id": command_id},
            ).one()
        late = row.state == "pending" and time.monotonic() >= deadline
        if row.state != "pending" or late:
            with db.transaction(write=True) as conn:
                conn.execute(
                    text("DELETE FROM control_commands WHERE id = :id"), {"id": command_id}
                )
        if late:
            msg = (
                f"no node answered {kind} within {timeout_s:g} s: start "
                "'toaster serve' on this database (queries need a running node)"
            )
            raise NoNodeError(msg)
        if row.state != "pending":
            answer = json.loads(row.answer_json or "null")
            if row.state == "failed":
                raise InvalidInputError(str(answer))
            return answer
        time.sleep(0.01)


def pending(conn: Connection, kinds: Iterable[str] | None = None) -> list[Command]:
    """Pending commands, oldest first (the node's side)."""
    rows = conn.execute(
        text("SELECT id, kind, args_json FROM control_commands WHERE state = 'pending' ORDER BY id")
    ).all()
    wanted = set(kinds) if kinds is not None else None
    return [
        Command(int(r.id), str(r.kind), _json(r.args_json))
        for r in rows
        if wanted is None or r.kind in wanted
    ]


def _json(text: object) -> Any:
    """Arguments as stored; text that is not JSON (a row written by hand) is returned as it is,
    and the node refuses it as arguments that are not a JSON object."""
    try:
        return json.loads(text)  # type: ignore[arg-type]
    except (TypeError, ValueError, RecursionError):
        return text


def finish(
    conn: Connection, command_id: int, answer: object = None, *, error: str | None = None
) -> None:
    """Record the node's answer (or the one-line error) of a command."""
    conn.execute(
        text(
            "UPDATE control_commands SET state = :state, answer_json = :answer, "
            "done_ns = :t WHERE id = :id"
        ),
        {
            "state": "failed" if error is not None else "done",
            "answer": json.dumps(error if error is not None else answer),
            "t": now_ns(),
            "id": command_id,
        },
    )
