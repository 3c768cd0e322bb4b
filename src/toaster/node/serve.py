"""Running a live node as ``toaster serve`` does: until SIGINT or SIGTERM, stopping between two
ticks (:func:`stop_on_signals`, which ``toaster run`` shares)."""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from toaster.node.live_node import LiveNode
from toaster.node.stats import LiveStats

log = logging.getLogger("toaster.node")


@contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event that SIGINT and SIGTERM set while inside (the loop stops between two ticks:
    the last tick is stored whole); the previous handlers come back at the end."""
    stop = threading.Event()

    def ask_stop(signum: int, _frame: object) -> None:
        log.info("signal %d: stopping after this tick", signum)
        stop.set()

    previous = {sig: signal.signal(sig, ask_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def serve(
    node: LiveNode,
    rate_hz: float = 30.0,
    *,
    seconds: float | None = None,
    status_every_s: float = 0.0,
) -> LiveStats:
    """Run a node until SIGINT or SIGTERM (or ``seconds``), stopping between two ticks; a
    status line every ``status_every_s`` seconds (0: none)."""
    with stop_on_signals() as stop:
        return node.run(rate_hz, stop=stop, seconds=seconds, status_every_s=status_every_s)


__all__ = ["serve", "stop_on_signals"]
