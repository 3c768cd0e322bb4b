"""The original's services, each a thin call into the control plane or the store.

Handlers run on rospy's threads, so they never touch the node's world or its database
handle: each call borrows a connection of its own (:class:`DbPool`); queries about the world
go through :func:`toaster.node.control.ask`, which the node answers between two ticks. A bad
request gives one warning line and a failed answer (``answer``/``boolAnswer`` false, or a
service error for the services whose response is empty), never an exception in the node.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from toaster.errors import InvalidInputError
from toaster.model import MAX_COORD, check_agent_id, check_id, shown
from toaster.node import control
from toaster.quoting import shell_word, visible
from toaster.ros1 import dbcalls
from toaster.ros1.messages import to_msg
from toaster.timeutil import check_ns
from toaster.world.drops import Refused
from toaster.world.live import check_entity, quaternion_to_rpy
from toaster.world.rosmsg import area_from_msg, quat, vec
from toaster.world.state import KIND_CODES

if TYPE_CHECKING:
    from toaster.db.database import Database

#: manage_stream flags (toaster_msgs/AddStream) -> toaster's ROS input streams
STREAM_FLAGS = {
    "tf": ("morseHuman", "pr2Robot", "spencerRobot"),
    "pose_topics": ("mocapObject", "adreamMocapHuman"),
    "ros4hri": ("mocapHuman", "groupHuman", "niutHuman"),
    "toaster_simu_human": ("toasterSimuHuman",),
    "toaster_simu_robot": ("toasterSimuRobot",),
    "toaster_simu_object": ("toasterSimuObject",),
}
CLASS_OF = {
    "monitor_all_agents": "agents",
    "monitor_all_humans": "humans",
    "monitor_all_robots": "robots",
}
AREA_IDS = ("ros1", "area_ids")  # settings scope and key: {area name: the original's number}


class DbPool:
    """Connections to the node's database for service threads (one per concurrent call)."""

    def __init__(self, url: str, before: Callable[[], object] = lambda: None) -> None:
        self.url = url
        self.before = before  # the node's flush_writes: a call sees the ticks before it
        self._free: list[Any] = []
        self._all: list[Any] = []
        self._lock = threading.Lock()

    @contextmanager
    def db(self) -> Iterator[Any]:
        """Borrow a connection, once the ticks computed before the call are stored
        (read-your-writes: the node writes them on its writer thread)."""
        from toaster.app.session import connect

        self.before()
        with self._lock:
            db = self._free.pop() if self._free else None
        if db is None:
            db = connect(self.url)
            with self._lock:
                self._all.append(db)
        try:
            yield db
        finally:
            with self._lock:
                self._free.append(db)

    def close(self) -> None:
        """Close every connection."""
        with self._lock:
            for db in self._all:
                db.close()
            self._all, self._free = [], []


class ServiceError(Refused):
    """A request refused with a one-line reason; ``field`` names the request field."""


def _pose_args(req: Any) -> dict[str, Any]:
    try:
        position, q = vec(req.pose.position), quat(req.pose.orientation)
        if any(abs(c) > MAX_COORD for c in position):
            msg = f"position {shown(list(position))} must lie within ±{MAX_COORD:g} m"
            raise ValueError(msg)
        rpy = quaternion_to_rpy(*q)
    except (ValueError, TypeError, OverflowError) as exc:
        msg = f"pose of {shown(req.id)} refused: {exc}"
        raise ServiceError(msg, "pose") from None
    return {"position": list(position), "rpy": list(rpy)}


def _entity_id(req: Any, kind: str) -> str:
    """The entity a request names, checked as the store will check it; joints are named
    "<agent>/<joint>" in toaster."""
    if not req.id:
        msg = "an entity id is required"
        raise ServiceError(msg, "id")
    if kind not in KIND_CODES:
        msg = f"type {shown(req.type)} is not object, human, robot or joint"
        raise ServiceError(msg, "type")
    joint = kind == "joint"
    entity_id = f"{req.ownerId}/{req.id}" if joint else str(req.id)
    try:
        return check_entity(entity_id, kind, req.ownerId if joint else "", req.id if joint else "")
    except Refused as exc:
        raise ServiceError(str(exc), exc.field) from None


def _checked_id(value: object, field: str, what: str, *, agent: bool = False) -> str:
    """``value`` if it is a valid id (an agent's: ``agent``), else a :class:`ServiceError`
    naming the request field."""
    try:
        return (check_agent_id if agent else check_id)(value, what)
    except InvalidInputError as exc:
        raise ServiceError(str(exc), field) from None


class Handlers:
    """Service handlers over a connection pool; ``ask_timeout`` bounds world queries;
    ``area_lists(timeout)`` gives the areas' entity lists as of the node's next tick."""

    def __init__(
        self,
        pool: DbPool,
        registry: Any,
        warn: Callable[[str], None],
        *,
        ask_timeout: float = 2.0,
        log: Callable[[str], None] | None = None,
        area_lists: Callable[[float], dict[str, Any] | None] | None = None,
    ) -> None:
        self.pool = pool
        self.area_lists = area_lists
        self.registry = registry
        self.warn = warn
        self.ask_timeout = ask_timeout
        self.log = log or warn

    def _ask(self, kind: str, args: dict[str, Any]) -> Any:
        with self.pool.db() as db:
            return control.ask(db, kind, args, self.ask_timeout)

    def _command(self, kind: str, args: dict[str, Any], wait_s: float = 1.0) -> None:
        """Queue a node command and wait (briefly) for its outcome; a failure raises."""
        with self.pool.db() as db:
            error = dbcalls.run_command(db, kind, args, wait_s)
        if error:
            msg = f"{kind}: {error}"
            raise ServiceError(msg, "id")

    # -- pdg -----------------------------------------------------------------------------------
    def manage_stream(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            for name, flags in STREAM_FLAGS.items():
                control.set_stream(db, name, any(bool(getattr(req, f)) for f in flags))
        return resp

    def _known(self, db: Database, entity_id: str, field: str, *, agent: bool = False) -> str:
        """``entity_id`` if the database has it (an agent: a human or robot), else a
        :class:`ServiceError` naming the request field."""
        _checked_id(entity_id, field, f"{field} ({'agent' if agent else 'object'} id)", agent=agent)
        kind = dbcalls.entity_kind(db, entity_id)
        if kind is None or (agent and kind not in ("human", "robot")):
            what = "human or robot" if agent else "entity"
            msg = f"{field} {shown(entity_id)} is no known {what}"
            raise ServiceError(msg, field)
        return entity_id

    def put_in_hand(self, req: Any, resp: Any) -> Any:
        """Refused (a service error: the response is empty) for an unknown object or agent."""
        _checked_id(req.jointName, "jointName", "joint name")
        with self.pool.db() as db:
            self._known(db, req.objectId, "objectId")
            self._known(db, req.agentId, "agentId", agent=True)
            control.put_in_hand(db, req.objectId, req.agentId, req.jointName)
        return resp

    def remove_from_hand(self, req: Any, resp: Any) -> Any:
        _checked_id(req.objectId, "objectId", "object id")
        with self.pool.db() as db:
            if not control.remove_from_hand(db, req.objectId):
                msg = f"objectId {shown(req.objectId)} is in no hand"
                raise ServiceError(msg, "objectId")
        return resp

    def set_entity_pose(self, req: Any, resp: Any) -> Any:
        """Moves a known entity only (as the original: its readers held the ids); an unknown
        one answers false instead of being created."""
        kind = str(req.type).lower() or "object"
        entity_id = _entity_id(req, kind)
        args = {"id": entity_id, "kind": kind, "known_only": True, **_pose_args(req)}
        if kind == "joint":
            args |= {"owner_id": req.ownerId, "joint": req.id}
        self._command("set_entity_pose", args)
        resp.answer = True
        return resp

    # -- toaster_simu --------------------------------------------------------------------------
    def add_entity(self, req: Any, resp: Any) -> Any:
        kind = str(req.type).lower()
        entity_id = _entity_id(req, kind)
        name = req.id if kind == "joint" else (req.name or req.id)  # a joint's skeleton name
        self._command(
            "add_entity", {"id": entity_id, "kind": kind, "owner_id": req.ownerId, "name": name}
        )
        resp.answer = True
        return resp

    def remove_entity(self, req: Any, resp: Any) -> Any:
        kind = str(req.type).lower()
        self._command("remove_entity", {"id": _entity_id(req, kind)})
        resp.answer = True
        return resp

    def set_entity_keyboard(self, req: Any, resp: Any) -> Any:
        """Chooses the one keyboard-controlled entity (a known one), kept in the database
        (setting keyboard.entity); toaster opens no keyboard window (docs/ros1.md)."""
        with self.pool.db() as db:
            dbcalls.set_keyboard_entity(db, self._known(db, req.id, "id"))
        resp.answer = True
        return resp

    # -- agent_monitor -------------------------------------------------------------------------
    def add_agent(self, req: Any, resp: Any) -> Any:
        """A known human or robot only (monitor_all_humans covers those still to come)."""
        with self.pool.db() as db:
            control.monitor_add(db, self._known(db, req.id, "id", agent=True))
        resp.answer = True
        return resp

    def remove_agent(self, req: Any, resp: Any) -> Any:
        """A known agent, or one still named in the monitored list."""
        _checked_id(req.id, "id", "agent id")
        with self.pool.db() as db:
            if req.id not in (dbcalls.control_state(db).agents or []):
                self._known(db, req.id, "id", agent=True)
            control.monitor_remove(db, req.id)
        resp.answer = True
        return resp

    def add_joint_to_agent(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            state = dbcalls.control_state(db)
            agents = state.agents if state.agents is not None else ["humans"]
            if req.agentId not in agents and not set(agents) & set(control.CLASSES):
                msg = (
                    f"add_joint_to_agent: {shown(req.agentId)} is not monitored: "
                    "call add_agent first"
                )
                raise ServiceError(msg, "agentId")
            control.monitor_add(db, req.agentId, joints=[req.jointName])
        resp.answer = True
        return resp

    def remove_joint_to_agent(self, req: Any, resp: Any) -> Any:
        _checked_id(req.agentId, "agentId", "agent id")
        _checked_id(req.jointName, "jointName", "joint name")
        with self.pool.db() as db:
            control.monitor_remove(db, req.agentId, joint=req.jointName)
        resp.answer = True
        return resp

    def remove_all_joints_to_agent(self, req: Any, resp: Any) -> Any:
        _checked_id(req.agentId, "agentId", "agent id")
        with self.pool.db() as db:
            joints = (dbcalls.control_state(db).joints or {}).get(req.agentId)
            if joints is None:
                self._known(db, req.agentId, "agentId", agent=True)
            for joint in joints or []:
                control.monitor_remove(db, req.agentId, joint=joint)
        resp.answer = True
        return resp

    def remove_all_agents(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            control.monitor_clear(db)
        return resp

    def monitor_all(self, which: str) -> Callable[[Any, Any], Any]:
        def handler(req: Any, resp: Any) -> Any:
            with self.pool.db() as db:
                control.monitor_all(db, which, bool(req.monitorAll))
            return resp

        return handler

    def print_all_monitored_agents(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            state = dbcalls.control_state(db)
        self.log(
            f"monitored agents: {state.agents if state.agents is not None else 'default'}"
            f"; except {state.excluded}; joints {state.joints or 'all'}"
        )
        return resp

    def pointing(self, req: Any, resp: Any) -> Any:
        _checked_id(req.pointingAgentId, "pointingAgentId", "pointing agent id", agent=True)
        _checked_id(req.pointingJoint or "rightHand", "pointingJoint", "joint name")
        args: dict[str, Any] = {
            "agent": req.pointingAgentId,
            "joint": req.pointingJoint or "rightHand",
        }
        for field, key in (
            ("pointingJointDistThreshold", "joint_distance"),
            ("angleThreshold", "angle"),
        ):
            value = float(getattr(req, field))
            if math.isfinite(value) and value > 0:
                args[key] = value
        if getattr(req, "timePointing", 0):
            try:
                args["t_ns"] = check_ns(int(req.timePointing), "timePointing")
            except InvalidInputError as exc:
                raise ServiceError(str(exc), "timePointing") from None
        found = self._ask("pointing", args)
        resp.pointedId = [str(entity_id) for entity_id, _ in found]
        resp.confidence = [float(conf) for _, conf in found]
        resp.answer = True
        return resp

    # -- area_manager --------------------------------------------------------------------------
    def add_area(self, req: Any, resp: Any) -> Any:
        area = req.myArea
        with self.pool.db() as db:
            number = dbcalls.area_number(db, int(area.id), str(area.name))
            if not area.name:
                area.name = f"area{number}"
            name, spec = area_from_msg(area)
            dbcalls.put_area(db, name, spec, number)
        resp.answer = True
        return resp

    def remove_area(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            name = dbcalls.area_name(db, int(req.id))
            if name is None or not db.store().remove_area(name):
                msg = f"remove_area: no area with id {req.id}"
                raise ServiceError(msg, "id")
            dbcalls.forget_area(db, name)
        resp.answer = True
        return resp

    def remove_all_areas(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            db.store().remove_all_areas()
            dbcalls.forget_area(db, None)
        return resp

    def _area_line(self, number: object, name: str, spec: Any, lists: Any) -> str:
        found = lists.get(name) if lists is not None else None
        if found is None:
            return f"area {number} {name!r}: {spec}"
        return (
            f"area {number} {name!r}: inside {found.inside}; upcoming {found.upcoming}; "
            f"leaving {found.leaving}; {spec}"
        )

    def _lists(self) -> Any:
        """The areas' entity lists from the node's next tick (None without a bridge)."""
        if self.area_lists is None:
            return None
        found = self.area_lists(self.ask_timeout)
        if found is None:
            msg = f"no tick of the node came within {self.ask_timeout:g} s"
            raise ServiceError(msg, "id")
        return found

    def print_area(self, req: Any, resp: Any) -> Any:
        """Logs the area and the entities inside it, upcoming and leaving."""
        with self.pool.db() as db:
            name = dbcalls.area_name(db, int(req.id))
            spec = db.store().areas().get(name) if name is not None else None
        if spec is None or name is None:
            msg = f"print_area: no area with id {req.id}"
            raise ServiceError(msg, "id")
        self.log(self._area_line(req.id, name, spec, self._lists()))
        resp.answer = True
        return resp

    def print_all_areas(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            numbers = dbcalls.area_numbers(db)
            areas = db.store().areas()
        lists = self._lists()
        for name, spec in areas.items():
            self.log(self._area_line(numbers.get(name, "?"), name, spec, lists))
        return resp

    def get_relative_position(self, req: Any, resp: Any) -> Any:
        _checked_id(req.subjectId, "subjectId", "subject id")
        _checked_id(req.targetId, "targetId", "target id")
        found = self._ask(
            "get_relative_position", {"subject": req.subjectId, "target": req.targetId}
        )
        resp.direction, resp.angleValue, resp.answer = found["direction"], found["angle"], True
        return resp

    def get_multiple_relative_position(self, req: Any, resp: Any) -> Any:
        for field in ("agentSubjectId", "objectSubjectId", "targetId"):
            _checked_id(getattr(req, field), field, field)
        found = self._ask(
            "get_multiple_relative_position",
            {"agent": req.agentSubjectId, "object": req.objectSubjectId, "target": req.targetId},
        )
        resp.direction, resp.angleValue, resp.answer = found["direction"], found["angle"], True
        return resp

    # -- database_manager ----------------------------------------------------------------------
    def execute(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            resp.boolAnswer, resp.results = dbcalls.execute(db, req)
        return resp

    def get_info(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            found = dbcalls.get_info(db, req)
        reg = self.registry

        def build(key: str, type_name: str) -> list[Any]:
            return [to_msg(reg.msg(type_name), d, reg) for d in found.get(key, [])]

        resp.resFactList.factList = build("facts", "Fact")
        resp.resEventList = build("events", "Event")
        resp.resId = build("ids", "Id")
        resp.resOntology = build("ontology", "Ontology")
        resp.resProperties = build("properties", "Property")
        resp.boolAnswer = any(
            found.get(k) for k in ("facts", "events", "ids", "ontology", "properties")
        )
        return resp

    def set_info(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            dbcalls.set_info(db, req)
        resp.answer = True
        return resp

    def plot_facts(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            path = dbcalls.plot_facts(db, req)
        script = shell_word(str(path.with_suffix(".gp").resolve()))
        self.log(
            f"plot_facts: wrote {visible(str(path.resolve()))} (draw it with gnuplot -p "
            f"{visible(script)})"
        )
        resp.boolAnswer = True
        return resp

    def load_save(self, req: Any, resp: Any) -> Any:
        """sqlstatus: SQLite's status code (0 when done); a refusal is also a warning line."""
        import sqlite3

        try:
            with self.pool.db() as db:
                dbcalls.load_save(db, str(req.fileName), bool(req.toSave))
            resp.sqlstatus = dbcalls.SQLITE_OK
            what = "saved to" if req.toSave else "loaded from"
            self.log(f"load_save: the database {what} {visible(str(req.fileName))}")
        except InvalidInputError as exc:
            self.warn(str(exc))
            resp.sqlstatus = dbcalls.SQLITE_ERROR
        except sqlite3.Error as exc:
            self.warn(f"load_save {visible(str(req.fileName))}: {exc}")
            resp.sqlstatus = getattr(exc, "sqlite_errorcode", dbcalls.SQLITE_CANTOPEN)
        return resp

    def table(self) -> list[tuple[str, str, Callable[[Any, Any], Any]]]:
        """(service name, toaster_msgs service type, handler) of every service."""
        out: list[tuple[str, str, Callable[[Any, Any], Any]]] = [
            ("/pdg/manage_stream", "AddStream", self.manage_stream),
            ("/pdg/put_in_hand", "PutInHand", self.put_in_hand),
            ("/pdg/remove_from_hand", "RemoveFromHand", self.remove_from_hand),
            ("/pdg/set_entity_pose", "SetEntityPose", self.set_entity_pose),
            ("/toaster_simu/add_entity", "AddEntity", self.add_entity),
            ("/toaster_simu/remove_entity", "RemoveEntity", self.remove_entity),
            ("/toaster_simu/set_entity_pose", "SetEntityPose", self.set_entity_pose),
            ("/agent_monitor/add_agent", "AddAgent", self.add_agent),
            ("/agent_monitor/remove_agent", "RemoveAgent", self.remove_agent),
            ("/agent_monitor/add_joint_to_agent", "AddJointToAgent", self.add_joint_to_agent),
            (
                "/agent_monitor/remove_joint_to_agent",
                "RemoveJointToAgent",
                self.remove_joint_to_agent,
            ),
            (
                "/agent_monitor/remove_all_joints_to_agent",
                "RemoveAllJointsToAgent",
                self.remove_all_joints_to_agent,
            ),
            ("/agent_monitor/remove_all_agents", "Empty", self.remove_all_agents),
            ("/agent_monitor/print_all_monitored_agents", "Empty", self.print_all_monitored_agents),
            ("/agent_monitor/pointing", "Pointing", self.pointing),
            ("/agent_monitor/pointing_time", "PointingTime", self.pointing),
            ("/area_manager/add_area", "AddArea", self.add_area),
            ("/area_manager/remove_area", "RemoveArea", self.remove_area),
            ("/area_manager/remove_all_areas", "Empty", self.remove_all_areas),
            ("/area_manager/print_area", "PrintArea", self.print_area),
            ("/area_manager/print_all_areas", "Empty", self.print_all_areas),
            (
                "/area_manager/get_relative_position",
                "GetRelativePosition",
                self.get_relative_position,
            ),
            (
                "/area_manager/get_multiple_relative_position",
                "GetMultiRelativePosition",
                self.get_multiple_relative_position,
            ),
            ("/database_manager/execute", "ExecuteDB", self.execute),
            ("/database_manager/get_info", "GetInfoDB", self.get_info),
            ("/database_manager/set_info", "SetInfoDB", self.set_info),
            ("/database_manager/plot_facts", "PlotFactsDB", self.plot_facts),
            ("/database_manager/load_save", "LoadSaveDB", self.load_save),
            ("/toaster_simu/set_entity_keyboard", "AddAgent", self.set_entity_keyboard),
        ]
        out += [
            (f"/agent_monitor/{name}", "MonitorAll", self.monitor_all(which))
            for name, which in CLASS_OF.items()
        ]
        return out
