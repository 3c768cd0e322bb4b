"""ROS 1 bridge of the live node: topics, TF and the original TOASTER services.

rospy comes from Debian's packages (``ros-core python3-rospy ...``), which serve the system
Python 3.11. It is pure Python, so the venv's interpreter of the same minor version can use it:
:func:`ros_path` appends Debian's ``dist-packages`` to ``sys.path`` (at the end, so the venv's
own packages win) the first time the bridge needs rospy. Nothing in toaster outside this
package imports rospy. :mod:`toaster.ros1.mapping` has no rospy import at all.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from toaster.errors import ToasterError
from toaster.ros1.messages import DEBIAN_DIST, ros_path

if TYPE_CHECKING:
    from toaster.ros1.bridge import Bridge

INSTALL_HINT = ("ROS 1 is not installed: apt-get install --no-install-recommends ros-core "
                "python3-rospy python3-rosbag python3-geometry-msgs python3-visualization-msgs "
                "python3-tf2-msgs python3-sensor-msgs python3-std-msgs")


class RosUnavailableError(ToasterError):
    """rospy (Debian's ROS 1 packages) cannot be imported."""


def import_rospy() -> Any:
    """``rospy``, or :class:`RosUnavailableError` with the apt-get line to install it."""
    ros_path()
    try:
        import genpy  # type: ignore[import-not-found]  # noqa: F401
        import rospy  # type: ignore[import-not-found]
        from geometry_msgs.msg import PoseStamped  # type: ignore[import-not-found]  # noqa: F401
        from tf2_msgs.msg import TFMessage  # type: ignore[import-not-found]  # noqa: F401
        from visualization_msgs.msg import MarkerArray  # type: ignore[import-not-found]  # noqa: F401
    except ImportError as exc:
        msg = f"{INSTALL_HINT} ({exc})"
        raise RosUnavailableError(msg) from None
    return rospy


def start_bridge(node: Any, **kwargs: Any) -> Bridge:
    """Start the ROS 1 bridge of a live node (see :func:`toaster.ros1.bridge.start_bridge`)."""
    from toaster.ros1.bridge import start_bridge as start

    return start(node, **kwargs)


__all__ = ["DEBIAN_DIST", "INSTALL_HINT", "RosUnavailableError", "import_rospy", "ros_path",
           "start_bridge"]
