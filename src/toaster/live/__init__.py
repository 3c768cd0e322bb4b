"""toaster beside a robot: the live node (:mod:`toaster.live.node`) and its control plane kept
in the database (:mod:`toaster.live.control`)."""

from toaster.live.node import LiveNode, LiveStats, Output, serve

__all__ = ["LiveNode", "LiveStats", "Output", "serve"]
