"""toaster beside a robot: the live node (:mod:`toaster.node.live_node`), its statistics and
fault handling, and its control plane kept in the database (:mod:`toaster.node.control`)."""

from toaster.node.live_node import LiveNode, LiveStats, Output
from toaster.node.serve import serve

__all__ = ["LiveNode", "LiveStats", "Output", "serve"]
