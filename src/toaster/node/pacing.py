"""When a live node's next tick may start (docs/live.md, "One tick"): as soon as input came,
within a budget of ticks that ``--rate`` sets.

The budget is a bucket of tick tokens refilled at ``rate / FOLLOW_GAP`` tokens a second (1.25 ×
the rate) and holding at most ``BURST``: a tick triggered by input takes one, and waits for one
when there is none. The long-run rate is capped as a fixed gap of ``FOLLOW_GAP`` periods after
each tick capped it, but input that comes early (a sensor's jitter, two messages sent together
after a stall, a pose just after an idle tick) no longer waits for the gap: at 30 Hz the gap
made a pose wait up to 27 ms for its tick, the p99 of the latency on a busy machine.
"""

from __future__ import annotations

import threading
import time

#: tokens come in at one every FOLLOW_GAP periods (at most 1.25 × --rate ticks a second)
FOLLOW_GAP = 0.8
#: ... and the bucket holds at most this many: two ticks in a row at once, no more
BURST = 2.0
#: without input the next tick comes this many periods after the previous one (not one: a
#: timer at the sensor's own rate beats against it, and half the poses then waited for the
#: gap after a tick that had nothing new; docs/live.md)
IDLE_WAIT = 1.5


class TickBudget:
    """The token bucket of one node's ticks; times are monotonic seconds."""

    def __init__(self, period: float, now: float) -> None:
        self.refill_s = FOLLOW_GAP * period  # seconds a token takes
        self.tokens = BURST
        self.at = now

    def _refill(self, now: float) -> None:
        if now > self.at:
            self.tokens = min(BURST, self.tokens + (now - self.at) / self.refill_s)
            self.at = now

    def take(self, now: float) -> None:
        """A tick starts now (it may be due for lack of input: the bucket may go below 0)."""
        self._refill(now)
        self.tokens -= 1.0

    def ready_at(self, now: float) -> float:
        """When a tick triggered by input may start (``now`` if a token is there)."""
        self._refill(now)
        return now if self.tokens >= 1.0 else now + (1.0 - self.tokens) * self.refill_s


def wait_for_tick(
    start: float, period: float, stop: threading.Event, wake: threading.Event, budget: TickBudget
) -> None:
    """Wait for the next tick: input (``wake``), once the budget has a tick for it; else
    ``IDLE_WAIT`` periods after ``start``; at once when ``stop`` is set."""
    deadline = start + IDLE_WAIT * period
    while not stop.is_set():
        now = time.monotonic()
        if now >= deadline:
            return
        if not wake.is_set():
            wake.wait(deadline - now)
            continue
        ready = budget.ready_at(now)
        if ready <= now:
            return
        stop.wait(min(ready, deadline) - now)
