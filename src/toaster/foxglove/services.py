"""The node's services on the Foxglove WebSocket protocol (JSON requests and responses, called
from the Foxglove app's Service Call panel): the control plane (:mod:`toaster.node.control`),
telling, and watching events on a channel of their own.

Each handler runs on an SDK thread with its own database connection, once the ticks computed
before the call are stored (the node's ``flush_writes``). A refused request fails the call
with a one-line reason.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from typing import Any

from toaster.errors import InvalidInputError

_S, _N = {"type": "string"}, {"type": "number"}


def _obj(props: dict[str, Any], required: tuple[str, ...] = ()) -> dict[str, Any]:
    return {"type": "object", "properties": props, "required": list(required)}


#: service name -> (request schema, what it does)
SERVICES: dict[str, tuple[dict[str, Any], str]] = {
    "/toaster/add_area": (
        _obj({"name": _S, "spec": {"type": "object"}}, ("name", "spec")),
        "add or replace an area (spec as `toaster area add --spec`)",
    ),
    "/toaster/remove_area": (_obj({"name": _S}, ("name",)), "remove an area"),
    "/toaster/monitor": (
        _obj(
            {
                "action": {"enum": ["add", "remove", "all", "clear"]},
                "agent": _S,
                "joint": _S,
                "which": {"enum": ["humans", "robots", "agents"]},
                "on": {"type": "boolean"},
            },
            ("action",),
        ),
        "agent_monitor's add / remove (agent, joint), all (which, on) and clear",
    ),
    "/toaster/stream": (
        _obj({"name": _S, "on": {"type": "boolean"}}, ("name", "on")),
        "switch an input stream on or off",
    ),
    "/toaster/set_pose": (
        _obj(
            {
                "id": _S,
                "x": _N,
                "y": _N,
                "z": _N,
                "yaw": _N,
                "kind": {"enum": ["human", "robot", "object"]},
            },
            ("id", "x", "y"),
        ),
        "place an entity (toaster_simu's set_entity_pose)",
    ),
    "/toaster/tell": (
        _obj(
            {
                "speaker": _S,
                "subject": _S,
                "property": _S,
                "target": _S,
                "value": _S,
                "listeners": {"type": "array", "items": _S},
            },
            ("speaker", "subject", "property"),
        ),
        "the speaker tells a fact to the listeners (default: everyone in its room)",
    ),
    "/toaster/watch": (
        _obj({"agent": _S, "subject": _S, "property": _S, "target": _S}),
        "open a channel /toaster/watch/N publishing the events matching the globs",
    ),
}


class Calls:
    """The handlers, on one database connection per server (calls are serialised)."""

    def __init__(self, server: Any) -> None:
        self.server, self.node = server, server.node
        self._db: Any = None
        self._lock = threading.Lock()
        self._watches = 0

    def db(self) -> Any:
        from toaster.app.session import connect

        if self._db is None:
            self._db = connect(self.node.db.url)
        return self._db

    def close(self) -> None:
        """Close the services' database connection."""
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None

    def call(self, name: str, request: Any) -> bytes:
        try:
            args = json.loads(bytes(request.payload) or b"{}")
        except ValueError:
            msg = f"{name}: the request is not JSON; send an object such as {{}}"
            raise InvalidInputError(msg) from None
        if not isinstance(args, dict):
            msg = f"{name}: the request is {type(args).__name__}, not a JSON object"
            raise InvalidInputError(msg)
        self.node.flush_writes()
        with self._lock:
            answer = getattr(self, name.rsplit("/", 1)[1])(args)
        return json.dumps({"ok": True, **answer}).encode()

    def add_area(self, a: dict[str, Any]) -> dict[str, Any]:
        from toaster.world.scenario import check_area

        spec = check_area(a["name"], a["spec"], "add_area")
        self.db().store().put_area(a["name"], spec, spec["owner"])
        return {}

    def remove_area(self, a: dict[str, Any]) -> dict[str, Any]:
        if not self.db().store().remove_area(a["name"]):
            msg = f"no area named {a['name']!r}: see `toaster area list`"
            raise InvalidInputError(msg)
        return {}

    def monitor(self, a: dict[str, Any]) -> dict[str, Any]:
        from toaster.node import control

        db, action = self.db(), a.get("action")
        if action == "add":
            state = control.monitor_add(db, a["agent"], [a["joint"]] if a.get("joint") else [])
        elif action == "remove":
            state = control.monitor_remove(db, a["agent"], a.get("joint") or None)
        elif action == "all":
            state = control.monitor_all(db, a.get("which", "humans"), bool(a.get("on", True)))
        elif action == "clear":
            state = control.monitor_clear(db)
        else:
            msg = f"monitor action {action!r}: use add, remove, all or clear"
            raise InvalidInputError(msg)
        return {"agents": state.agents, "joints": state.joints}

    def stream(self, a: dict[str, Any]) -> dict[str, Any]:
        from toaster.node import control

        control.set_stream(self.db(), a["name"], bool(a["on"]))
        return {}

    def set_pose(self, a: dict[str, Any]) -> dict[str, Any]:
        from toaster.node import control

        position = [float(a["x"]), float(a["y"]), float(a.get("z", 0.0))]
        args = {
            "id": a["id"],
            "position": position,
            "yaw": float(a.get("yaw", 0.0)),
            "kind": a.get("kind", "object"),
        }
        return {"command": control.submit(self.db(), "set_entity_pose", args)}

    def tell(self, a: dict[str, Any]) -> dict[str, Any]:
        from toaster.beliefs.tell import tell
        from toaster.model import Fact

        fact = Fact(a["subject"], a["property"], a.get("target", ""), a.get("value", "true"))
        return {"learnt": tell(self.db(), a["speaker"], fact, listeners=a.get("listeners"))}

    def watch(self, a: dict[str, Any]) -> dict[str, Any]:
        import foxglove
        from toaster.outputs.foxglove import EVENTS_TOPIC, JSON_SCHEMAS

        patterns = {k: str(a[k]) for k in ("agent", "subject", "property", "target") if a.get(k)}
        self._watches += 1
        topic = f"/toaster/watch/{self._watches}"
        channel = foxglove.Channel(
            topic, schema=JSON_SCHEMAS[EVENTS_TOPIC], context=self.server.context
        )
        self.server.output.watches.append((channel, patterns))
        return {"topic": topic}


def node_services(server: Any) -> tuple[Calls | None, list[Any]]:
    """The :data:`SERVICES` of ``server``'s node as foxglove Services, and what answers them
    (none without a database)."""
    from foxglove import MessageSchema, Schema, Service, ServiceSchema

    if server.node.db is None:
        return None, []
    calls = Calls(server)
    out = []
    for name, (request, _what) in SERVICES.items():
        schema = ServiceSchema(
            name.rsplit("/", 1)[1],
            request=MessageSchema(
                encoding="json",
                schema=Schema(
                    name=f"toaster.{name.rsplit('/', 1)[1]}.Request",
                    encoding="jsonschema",
                    data=json.dumps(request).encode(),
                ),
            ),
        )
        out.append(Service(name, schema=schema, handler=_handler(calls, name)))
    return calls, out


def _handler(calls: Calls, name: str) -> Callable[[Any], bytes]:
    def handle(request: Any) -> bytes:
        try:
            return calls.call(name, request)
        except KeyError as exc:
            msg = f"{name}: the request needs field {exc.args[0]!r}"
            raise InvalidInputError(msg) from None

    return handle
