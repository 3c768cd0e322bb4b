"""ROS 2's names and QoS on DDS, as rmw_cyclonedds (and every DDS rmw) puts them on the wire.

Checked against the ROS 2 design article "Topic and Service name mapping to DDS"
(design.ros2.org/articles/topic_and_service_names.html): a topic ``/a/b`` is the DDS topic
``rt/a/b``; a service ``/a/s`` is the request topic ``rq/a/sRequest`` and the reply topic
``rr/a/sReply``. Type names follow rosidl's DDS IDL (``pkg/msg/T`` is
``pkg::msg::dds_::T_``, a service's parts ``pkg::srv::dds_::S_Request_`` /
``S_Response_``). rmw_cyclonedds puts a sample identity in front of every request and reply
(``cdds_request_header_t {uint64 guid; int64 seq;}``, rmw_cyclonedds_cpp/src/serdata.hpp):
:data:`REQUEST_HEADER`.
"""

from __future__ import annotations

import os

from toaster.errors import InvalidInputError

#: the fields rmw_cyclonedds writes before a request's or reply's own (serdata.hpp)
REQUEST_HEADER = (("guid", "uint64"), ("seq", "int64"))
#: ROS 2's domain ids (ROS_DOMAIN_ID): 0..232 is what every rmw accepts (DDS ports)
MAX_DOMAIN_ID = 232


def _bare(name: str) -> str:
    if not name.startswith("/") or name.endswith("/") or "//" in name:
        msg = f"ROS name {name!r} must be absolute (/a/b), without a trailing or double slash"
        raise InvalidInputError(msg)
    return name[1:]


def topic(name: str) -> str:
    """The DDS topic of ROS 2 topic ``name`` (``/tf`` -> ``rt/tf``)."""
    return f"rt/{_bare(name)}"


def request_topic(service: str) -> str:
    """The DDS request topic of a ROS 2 service (``/a/s`` -> ``rq/a/sRequest``)."""
    return f"rq/{_bare(service)}Request"


def reply_topic(service: str) -> str:
    """The DDS reply topic of a ROS 2 service (``/a/s`` -> ``rr/a/sReply``)."""
    return f"rr/{_bare(service)}Reply"


def dds_type(msgtype: str) -> str:
    """The DDS type name of ``pkg/msg/T`` (or ``pkg/srv/S_Request``): ``pkg::msg::dds_::T_``."""
    package, kind, name = msgtype.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def domain_id(value: int | str | None = None) -> int:
    """The domain: ``value``, else ``ROS_DOMAIN_ID``, else 0 (as ROS 2 does)."""
    raw = value if value is not None else os.environ.get("ROS_DOMAIN_ID", "").strip() or 0
    try:
        found = int(raw)
    except ValueError:
        found = -1
    if not 0 <= found <= MAX_DOMAIN_ID:
        msg = f"ROS 2 domain id {raw!r} must be an integer 0..{MAX_DOMAIN_ID} (ROS_DOMAIN_ID)"
        raise InvalidInputError(msg)
    return found
