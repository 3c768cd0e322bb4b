"""Foxglove beside a live node (``toaster serve --foxglove``; the ``foxglove`` extra): the
WebSocket server (:mod:`toaster.foxglove.server`) and the node's services on it
(:mod:`toaster.foxglove.services`). The channels are :mod:`toaster.outputs.foxglove`'s, shared
with Foxglove recordings. docs/foxglove.md."""
