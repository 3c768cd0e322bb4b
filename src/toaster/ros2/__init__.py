"""ROS 2 bridge of the live node, over DDS without a ROS 2 install (``toaster[ros2]``:
cyclonedds and rosbags from PyPI). Nothing outside this package imports cyclonedds, and this
package imports it only when a bridge starts (``toaster --help`` stays fast). docs/ros2.md."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from toaster.ros2.bridge import Ros2Bridge


def start_bridge(node: Any, **kwargs: Any) -> Ros2Bridge:
    """Start the ROS 2 bridge of a live node (see :func:`toaster.ros2.bridge.start_bridge`)."""
    from toaster.ros2.bridge import start_bridge as start

    return start(node, **kwargs)


__all__ = ["start_bridge"]
