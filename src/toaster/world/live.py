"""A source fed from Python: push poses from your own sensors, they are applied at the next tick."""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from toaster.timeutil import now_ns
from toaster.world.state import World


class LiveSource:
    """Thread-safe queue of poses; ``advance`` applies what was pushed since the last tick."""

    def __init__(self, name: str = "live") -> None:
        self.name = name
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self._lock = threading.Lock()
        self._queue: list[tuple[str, str, int, Sequence[float], Sequence[float], float]] = []
        self._known: set[str] = set()

    def push(self, entity_id: str, position: Sequence[float], *, yaw: float = 0.0,
             rpy: Sequence[float] | None = None, t_ns: int | None = None,
             kind: str = "human", confidence: float = 1.0) -> None:
        """Queue a pose (x, y[, z] in metres; time defaults to the wall clock)."""
        pos = [*map(float, position), 0.0, 0.0][:3]
        angles = list(rpy) if rpy is not None else [0.0, 0.0, float(yaw)]
        with self._lock:
            self._queue.append((entity_id, kind, now_ns() if t_ns is None else t_ns, pos,
                                angles, confidence))

    def setup(self, world: World) -> None:
        """Nothing to register up front; entities are added when first pushed."""

    def advance(self, world: World, t_ns: int) -> None:
        """Apply queued poses with time ≤ ``t_ns``; later ones wait for a later tick."""
        with self._lock:
            ready = [q for q in self._queue if q[2] <= t_ns]
            self._queue = [q for q in self._queue if q[2] > t_ns]
        if not ready:
            return
        for eid, kind, *_ in ready:
            if eid not in world.index:
                world.add_entity(eid, kind)
        world.observe(self.name, [q[0] for q in ready], np.array([q[2] for q in ready]),
                      np.array([q[3] for q in ready]), np.array([q[4] for q in ready]),
                      np.array([q[5] for q in ready]))
