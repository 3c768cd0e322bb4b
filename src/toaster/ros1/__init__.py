"""ROS 1 bridge of the live node: topics, TF and the original TOASTER services.

rospy comes from Debian's packages (``ros-core python3-rospy ...``), which serve the system
Python 3.11. It is pure Python, so the venv's interpreter of the same minor version can use it:
:func:`ros_path` appends Debian's ``dist-packages`` to ``sys.path`` (at the end, so the venv's
own packages win) the first time the bridge needs rospy. Nothing in toaster outside this
package imports rospy. :mod:`toaster.world.rosmsg` has no rospy import at all.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from toaster.ros1.available import INSTALL_HINT, RosUnavailableError, import_rospy
from toaster.ros1.messages import DEBIAN_DIST, ros_path

if TYPE_CHECKING:
    from toaster.ros1.bridge import Bridge

#: the shipped RViz config (``rviz -d``): the marker topics, /tf, fixed frame map
RVIZ_CONFIG = Path(__file__).with_name("toaster.rviz")


def start_bridge(node: Any, **kwargs: Any) -> Bridge:
    """Start the ROS 1 bridge of a live node (see :func:`toaster.ros1.bridge.start_bridge`)."""
    from toaster.ros1.bridge import start_bridge as start

    return start(node, **kwargs)


__all__ = [
    "DEBIAN_DIST",
    "INSTALL_HINT",
    "RVIZ_CONFIG",
    "RosUnavailableError",
    "import_rospy",
    "ros_path",
    "start_bridge",
]
