"""Per-entity time-stamped ring buffers, stored as one (entities × capacity) block of arrays.

A sample is appended for an entity only when its perception time is strictly newer than its
last sample (as the original's TRBuffer). Samples older than ``horizon_ns`` behind the newest
sample of the whole world are ignored, so the buffer is bounded in time (default 3.3 s) as well
as in count (default 100 samples).
"""

from __future__ import annotations

import numpy as np

from toaster.timeutil import NS_PER_S

DEFAULT_HORIZON_NS = 3_300_000_000
NO_TIME = np.iinfo(np.int64).min
_BIG = np.iinfo(np.int64).max


class History:
    """Ring buffers of (time, position, roll-pitch-yaw) for every entity row of a world."""

    def __init__(self, capacity: int = 100, horizon_ns: int = DEFAULT_HORIZON_NS) -> None:
        self.capacity = int(capacity)
        self.horizon_ns = int(horizon_ns)
        self.t = np.full((0, self.capacity), NO_TIME, dtype=np.int64)
        self.pos = np.zeros((0, self.capacity, 3))
        self.rpy = np.zeros((0, self.capacity, 3))
        self.head = np.zeros(0, dtype=np.int64)
        self.last_t = np.zeros(0, dtype=np.int64)
        self.newest = NO_TIME

    def _grow(self, rows: int) -> None:
        old = self.t.shape[0]
        if rows <= old:
            return
        new = max(rows, 2 * old, 16)
        grow = new - old
        self.t = np.concatenate([self.t, np.full((grow, self.capacity), NO_TIME, np.int64)])
        self.pos = np.concatenate([self.pos, np.zeros((grow, self.capacity, 3))])
        self.rpy = np.concatenate([self.rpy, np.zeros((grow, self.capacity, 3))])
        self.head = np.concatenate([self.head, np.zeros(grow, np.int64)])
        self.last_t = np.concatenate([self.last_t, np.full(grow, NO_TIME, np.int64)])

    def append(
        self, t_ns: np.ndarray, pos: np.ndarray, rpy: np.ndarray, rows: np.ndarray | None = None
    ) -> int:
        """Append the current state of entity rows whose time is newer; return how many."""
        n = len(t_ns)
        self._grow(n)
        if rows is None:
            rows = np.arange(n)
        newer = rows[t_ns[rows] > self.last_t[rows]]
        if newer.size == 0:
            return 0
        slot = self.head[newer]
        self.t[newer, slot] = t_ns[newer]
        self.pos[newer, slot] = pos[newer]
        self.rpy[newer, slot] = rpy[newer]
        self.head[newer] = (slot + 1) % self.capacity
        self.last_t[newer] = t_ns[newer]
        self.newest = max(self.newest, int(t_ns[newer].max()))
        return int(newer.size)

    def clear_rows(self, rows: np.ndarray) -> None:
        """Forget the samples of entity rows (an entity that left and comes back)."""
        rows = np.asarray(rows)
        rows = rows[rows < self.t.shape[0]]  # rows never recorded have nothing to forget
        self.t[rows] = NO_TIME
        self.last_t[rows] = NO_TIME

    def _valid(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        times = self.t[rows]
        return times, (times != NO_TIME) & (times >= self.newest - self.horizon_ns)

    def latest_at_or_before(
        self, rows: np.ndarray, t_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For each row, the newest sample with time ≤ t_ref: (found, time, position, rpy)."""
        times, valid = self._valid(rows)
        ok = valid & (times <= np.asarray(t_ref, dtype=np.int64).reshape(-1, 1))
        masked = np.where(ok, times, NO_TIME)
        slot = masked.argmax(axis=1)
        found = np.asarray(ok.any(axis=1))  # (R,) bool
        return found, times[np.arange(len(rows)), slot], self.pos[rows, slot], self.rpy[rows, slot]

    def oldest_after(
        self, rows: np.ndarray, t_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For each row, the oldest sample with time > t_ref (the original's window rule)."""
        times, valid = self._valid(rows)
        ok = valid & (times > np.asarray(t_ref, dtype=np.int64).reshape(-1, 1))
        slot = np.where(ok, times, _BIG).argmin(axis=1)
        found = np.asarray(ok.any(axis=1))  # (R,) bool
        return found, times[np.arange(len(rows)), slot], self.pos[rows, slot], self.rpy[rows, slot]

    def window_sample(
        self, rows: np.ndarray, window_ns: int, max_gap_ns: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reference sample for a motion window ending at each row's newest sample.

        The newest sample at or before ``t - window`` is used when it is at most ``max_gap_ns``
        old (so sparse tracks, e.g. 2.5 Hz, still give a speed); otherwise the original's rule:
        the oldest sample strictly after ``t - window``. Returns (elapsed_ns, position, rpy);
        elapsed is 0 where only the newest sample exists (speed then counts as 0, not NaN).
        """
        now = self.last_t[rows]
        found, t_b, p_b, r_b = self.latest_at_or_before(rows, now - window_ns)
        use_b = found & (now - t_b <= max_gap_ns)
        _, t_a, p_a, r_a = self.oldest_after(rows, now - window_ns)
        t_ref = np.where(use_b, t_b, t_a)
        pos = np.where(use_b[:, None], p_b, p_a)
        rpy = np.where(use_b[:, None], r_b, r_a)
        elapsed = np.where(now == NO_TIME, 0, now - t_ref)
        return elapsed, pos, rpy

    def as_of(self, rows: np.ndarray, t_ns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose of each row as of ``t_ns`` (latest sample ≤ t, else the oldest one kept).

        Returns (found, position, rpy); ``found`` is False for rows with no sample at all.
        """
        found, _, pos, rpy = self.latest_at_or_before(rows, np.full(len(rows), t_ns))
        any_found, _, pos_a, rpy_a = self.oldest_after(rows, np.full(len(rows), t_ns))
        pos = np.where(found[:, None], pos, pos_a)
        rpy = np.where(found[:, None], rpy, rpy_a)
        return found | any_found, pos, rpy

    @staticmethod
    def seconds(ns: np.ndarray) -> np.ndarray:
        """Nanoseconds to float seconds."""
        return np.asarray(ns, dtype=float) / NS_PER_S
