"""Debounce: a reported boolean state that resists noise, per world row, vectorised.

Rule (config ``min_duration``, seconds per property): the reported state flips only when the
raw state has been the new value continuously since the last time it was the old value, and
that last contrary time is at least ``min_duration`` ago. Times are the rows' perception
times, so sparse data stays exact: at 2.5 Hz (samples 0.4 s apart) a change is reported at
once when ``min_duration`` ≤ 0.4 s, while at 30 Hz a flip needs ``min_duration`` of
consistent samples. Rows not evaluated in a tick count as raw False at their perception time
(the fact is absent); rows never seen before, or whose time went backwards, flip at once.
``min_duration`` 0 reports the raw state unchanged. For IsMoving, a track's first sample
(speed 0: no motion measurable yet) is evidence of "not moving": a standing person seen with
noise starts and stays not moving, a walker seen at 30 Hz is reported ``min_duration`` later.
"""

from __future__ import annotations

import numpy as np

from toaster.world.history import NO_TIME


def _step(
    state: np.ndarray, since: np.ndarray, raw: np.ndarray, clock: np.ndarray, min_ns: int
) -> tuple[np.ndarray, np.ndarray]:
    """The rule of the module for aligned arrays: (new reported state, new time of the last
    evidence agreeing with it)."""
    differ = raw != state
    timed = (since != NO_TIME) & (clock != NO_TIME)
    elapsed = np.where(timed, clock, 0) - np.where(timed, since, 0)
    flip = differ & (~timed | (elapsed >= min_ns) | (elapsed < 0))
    return np.where(flip, raw, state), np.where(~differ | flip, clock, since)


class Debouncer:
    """Reported state and time of the last agreeing evidence, indexed by world row."""

    __slots__ = ("min_ns", "since", "state")

    def __init__(self, min_ns: int) -> None:
        self.min_ns = int(min_ns)
        self.state = np.zeros(0, bool)
        self.since = np.zeros(0, np.int64)

    def reset(self) -> None:
        """Forget every row (a new world)."""
        self.state = np.zeros(0, bool)
        self.since = np.zeros(0, np.int64)

    def update(self, rows: np.ndarray, raw: np.ndarray, clock: np.ndarray) -> np.ndarray:
        """The reported state of ``rows`` given their raw state; others are raw False.

        ``clock`` holds every row's evidence time (ns), e.g. ``world.t_ns[:world.n]``; rows
        only grow, so the state arrays grow with it.
        """
        if self.min_ns <= 0:
            return np.asarray(raw, bool)
        n = len(clock)
        old = len(self.state)
        if n > old:
            self.state = np.concatenate([self.state, np.zeros(n - old, bool)])
            self.since = np.concatenate([self.since, np.full(n - old, NO_TIME, np.int64)])
        full = np.zeros(n, bool)
        full[rows] = raw
        self.state[:n], self.since[:n] = _step(
            self.state[:n], self.since[:n], full, clock, self.min_ns
        )
        return self.state[rows].copy()


class PairDebouncer:
    """The same rule for pair facts (mover × target), keyed by an int64 pair key.

    Only the pairs evaluated in a tick are kept (within range, mover moving): a pair that is
    not evaluated is dropped at once (there is no value to report for it). A pair evaluated
    anew starts as not reported, with ``before`` (the mover's previous sample time: the pair
    was absent then) as its last contrary evidence, so at 30 Hz it is reported after
    ``min_duration`` of consistent evidence and noise at a range edge does not flicker; at
    2.5 Hz (samples 0.4 s apart) it is reported at once. Without ``before`` it takes its raw
    state at once, as a row never seen does.
    """

    __slots__ = ("keys", "min_ns", "since", "state")

    def __init__(self, min_ns: int) -> None:
        self.min_ns = int(min_ns)
        self.reset()

    def reset(self) -> None:
        """Forget every pair (a new world)."""
        self.keys = np.zeros(0, np.int64)
        self.state = np.zeros(0, bool)
        self.since = np.zeros(0, np.int64)

    def update(
        self, keys: np.ndarray, raw: np.ndarray, clock: np.ndarray, before: np.ndarray | None = None
    ) -> np.ndarray:
        """The reported state of the pairs ``keys`` (unique) given their raw state, the time
        of that evidence (ns, one per pair) and, optionally, the time of the evidence before
        it (``NO_TIME`` where there is none)."""
        raw = np.asarray(raw, bool)
        if self.min_ns <= 0:
            return raw
        order = np.argsort(keys, kind="stable")
        k, r, c = keys[order], raw[order], clock[order]
        if before is None:
            new_state, new_since = r, np.full(len(k), NO_TIME, np.int64)
        else:
            b = np.asarray(before, np.int64)[order]
            new_state, new_since = np.where(b == NO_TIME, r, False), b
        if len(self.keys):
            pos = np.minimum(np.searchsorted(self.keys, k), len(self.keys) - 1)
            found = self.keys[pos] == k
            state = np.where(found, self.state[pos], new_state)
            since = np.where(found, self.since[pos], new_since)
        else:
            state, since = new_state.copy(), new_since.copy()
        state, since = _step(state, since, r, c, self.min_ns)
        self.keys, self.state, self.since = k, state, since
        out = np.empty(len(k), bool)
        out[order] = state
        return out
