"""The time of a live tick (docs/time.md, "Ticks"): the perception time, as the original's
facts carry their entity's time.

``perception`` (the default): a tick that applies stamped samples is at the newest of their
stamps, if it lies within ``max_lag`` of the wall clock (the samples a tick applies are never in
the future: a pose stamped later waits). A tick that applies none is at the wall clock minus
the lag of the last perceived tick, so that an idle tick does not run ahead of the next sample.
Stamps further back (unsynchronised clocks, a bag played without ``use_sim_time``) put the tick
on the wall clock, with one warning line. ``wall``: every tick is at the wall clock (what
toaster did before issue 27). The caller keeps time moving on (``max(t, last + 1)``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from toaster.errors import InvalidInputError
from toaster.timeutil import NS_PER_S, now_ns
from toaster.world.state import World

#: what ``toaster serve --stamp`` takes
STAMP_MODES = ("perception", "wall")


class TickClock:
    """Chooses each tick's time from the sources' pending stamps and the wall clock."""

    def __init__(
        self,
        mode: str,
        max_lag_s: float,
        warn: Callable[[str], None],
        wall: Callable[[], int] = now_ns,
    ) -> None:
        if mode not in STAMP_MODES:
            msg = f"stamp {mode!r} must be one of {', '.join(STAMP_MODES)}"
            raise InvalidInputError(msg)
        self.mode = mode
        self.max_lag_ns = int(max_lag_s * NS_PER_S)
        self.warn = warn
        self.wall = wall  # tests give a clock of their own
        self.lag_ns = 0  # wall clock minus perception time at the last perceived tick
        self.wall_ticks = 0  # ticks put on the wall clock because stamps were too old
        self._warned = False

    def now(self, sources: Iterable[Any], world: World) -> int:
        """The time of the next tick, given the sources it will advance."""
        wall = self.wall()
        if self.mode == "wall":
            return wall
        newest: int | None = None
        for source in sources:
            peek = getattr(source, "newest_stamp", None)
            if peek is None or not world.sources_enabled.get(getattr(source, "name", ""), True):
                continue
            try:
                stamp = peek(wall)
            except Exception:  # the source's advance reports it in the tick
                continue
            if stamp is not None and (newest is None or stamp > newest):
                newest = stamp
        if newest is None:
            return wall - self.lag_ns
        lag = wall - newest
        if 0 <= lag <= self.max_lag_ns:
            self.lag_ns = lag
            return newest
        self.lag_ns = 0
        self.wall_ticks += 1
        if not self._warned:
            self._warned = True
            self.warn(
                f"pose stamps are {lag / NS_PER_S:.1f} s behind the wall clock (more than "
                f"max_stamp_lag, {self.max_lag_ns / NS_PER_S:g} s): such ticks use the wall "
                "clock; synchronise the clocks (NTP), play bags with --clock and use_sim_time, "
                "or run toaster serve --stamp wall"
            )
        return wall
