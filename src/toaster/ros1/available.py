"""Whether ROS 1 can be used: rospy from Debian's packages, or an error with the apt-get line.

Apart from :mod:`toaster.ros1.messages` (which must import nothing from toaster), every module of
the bridge takes these names from here, not from the package, so the package and the bridge
import no circle.
"""

from __future__ import annotations

from typing import Any

from toaster.errors import ToasterError
from toaster.ros1.messages import ros_path

INSTALL_HINT = (
    "ROS 1 is not installed: apt-get install --no-install-recommends ros-core "
    "python3-rospy python3-rosbag python3-geometry-msgs python3-visualization-msgs "
    "python3-tf2-msgs python3-sensor-msgs python3-std-msgs"
)


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
