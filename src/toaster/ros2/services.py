"""The node's services as ROS 2 services over DDS: each a request reader on ``rq/<name>Request``
and a reply writer on ``rr/<name>Reply`` (:mod:`toaster.ros2.names`), the request and reply
carrying rmw_cyclonedds' sample identity (``guid``, ``seq``), copied from request to reply so
that the calling client takes its own answer.

The handlers are the ROS 1 bridge's (:class:`toaster.ros1.services.Handlers`, plain Python over
the control plane): a request is handed to them with its original field names
(:class:`Request`: ``req.agentId`` reads ``agent_id``), their answer collected in a
:class:`Fields` and built as the ROS 2 response. Calls run on a small thread pool, never on
cyclonedds' receive thread (a call may wait for the node's next tick).
"""

from __future__ import annotations

import functools
import logging
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from toaster.ros1 import dbcalls
from toaster.ros1.bridge import STATUS_SERVICE
from toaster.ros1.services import DbPool, Handlers
from toaster.ros2 import names
from toaster.ros2.dds import qos, reader_qos

log = logging.getLogger("toaster.ros2")


@functools.cache
def _snake(name: str) -> str:
    from toaster.outputs.recording.msgs import snake

    return snake(name)


class Request:
    """A ROS 2 request (or a part of it) read by the original's field names."""

    __slots__ = ("_msg",)

    def __init__(self, msg: Any) -> None:
        self._msg = msg

    def __getattr__(self, name: str) -> Any:
        msg = self._msg
        value = getattr(msg, name) if hasattr(msg, name) else getattr(msg, _snake(name))
        return wrap(value)


def wrap(value: Any) -> Any:
    """Messages as :class:`Request`, lists item by item, other values as they are."""
    if hasattr(value, "__dataclass_fields__"):
        return Request(value)
    if isinstance(value, list):
        return [wrap(v) for v in value]
    return value


class Fields:
    """A response as the handlers fill it (``resp.resFactList.factList = ...``)."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        inner = Fields()
        setattr(self, name, inner)
        return inner

    def plain(self) -> dict[str, Any]:
        return {k: _plain(v) for k, v in vars(self).items()}


def _plain(value: Any) -> Any:
    if isinstance(value, Fields):
        return value.plain()
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


class Ros2Handlers(Handlers):
    """The ROS 1 handlers; get_info answers plain fields (no genpy here)."""

    def get_info(self, req: Any, resp: Any) -> Any:
        with self.pool.db() as db:
            found = dbcalls.get_info(db, req)
        resp.resFactList = {"factList": found.get("facts", [])}
        resp.resEventList = found.get("events", [])
        resp.resId = found.get("ids", [])
        resp.resOntology = found.get("ontology", [])
        resp.resProperties = found.get("properties", [])
        resp.boolAnswer = any(
            found.get(k) for k in ("facts", "events", "ids", "ontology", "properties")
        )
        return resp


class Server:
    """Serves the bridge's node: the original's services, ``/toaster/get_status`` and
    ``/area_manager/publish_all_areas``."""

    def __init__(self, bridge: Any, workers: int = 4) -> None:
        self.bridge = bridge
        self.types = bridge.types
        self.pool: DbPool | None = None
        self.executor = ThreadPoolExecutor(workers, thread_name_prefix="toaster-ros2-srv")
        table: list[tuple[str, str, Any]] = [(STATUS_SERVICE, "std_srvs/Trigger", self._get_status)]
        db = bridge.node.db
        url = getattr(db, "url", "") if db is not None else ""
        if not url or ":memory:" in url:
            bridge.node.warn(
                "ROS 2 services other than /toaster/get_status are off: they need a "
                "database file or server that a second connection can open (not :memory:)"
            )
        else:
            self.pool = DbPool(url, before=getattr(bridge.node, "flush_writes", lambda: None))
            areas_out = bridge.output.areas_out
            handlers = Ros2Handlers(
                self.pool,
                None,
                lambda line: bridge.warnings.add(line, line),
                log=log.info,
                area_lists=areas_out.ask,
            )

            def publish_all_areas(req: Any, resp: Any) -> Any:
                on = areas_out.toggle()
                bridge.output._last_areas = None  # send it again when switched back on
                log.info("/area_manager/areaList is %s", "on" if on else "off")
                return resp

            table += [
                *handlers.table(),
                ("/area_manager/publish_all_areas", "Empty", publish_all_areas),
            ]
        for name, service_type, handler in table:
            self._serve(name, service_type, handler)

    def _get_status(self, req: Any, resp: Any) -> Any:
        resp.success, resp.message = True, self.bridge.node.status()
        return resp

    def _serve(self, name: str, service_type: str, handler: Any) -> None:
        dds = self.bridge.dds
        request_cls = self.types.wrapped(service_type, "Request")
        reply_cls = self.types.wrapped(service_type, "Response")
        reply_type = self.types.service_part(service_type, "Response")
        reply_name = f"{reply_type.split('/')[0]}::srv::dds_::{reply_type.split('/')[2]}_body_"
        writer = dds.raw_writer(names.reply_topic(name), reply_cls, qos("reliable"))
        answer = functools.partial(self._answer, name, handler, writer, reply_cls, reply_type)

        def on_request(sample: Any) -> None:
            self.executor.submit(answer, reply_name, sample)

        dds.raw_reader(names.request_topic(name), request_cls, reader_qos("reliable"), on_request)

    def _answer(
        self,
        name: str,
        handler: Any,
        writer: Any,
        reply_cls: Any,
        reply_type: str,
        reply_name: str,
        sample: Any,
    ) -> None:
        resp = Fields()
        fields = {f for f, _ in self.types.fields(reply_type)}
        try:
            handler(Request(sample.body), resp)
            values = resp.plain()
        except Exception as exc:  # a bad request fails this call only
            line = f"{name}: {type(exc).__name__}: {exc}".splitlines()[0]
            self.bridge.drops.drop(name, getattr(exc, "field", "request"), line, "refused")
            self.bridge.warnings.add(line, line)
            values = {k: False for k in ("answer", "bool_answer") if k in fields}
        try:
            body = self.types.build(reply_type, values, reply_name)
            writer.write(reply_cls(guid=sample.guid, seq=sample.seq, body=body))
        except Exception as exc:  # an answer that cannot be built is a warning, not a crash
            line = f"{name}: reply not sent: {exc}".splitlines()[0]
            self.bridge.warnings.add(line, line)

    def close(self) -> None:
        self.executor.shutdown(wait=False, cancel_futures=True)
        if self.pool is not None:
            self.pool.close()
