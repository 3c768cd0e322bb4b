"""A live node's tick counters and status windows (the periodic ``toaster serve`` line)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

#: a status window keeps at most this many tick durations (the newest)
WINDOW_TICKS = 100_000


@dataclass
class LiveStats:
    """Counters of a live run, and the ticks of the current status window."""

    ticks: int = 0
    overruns: int = 0
    worst_ms: float = 0.0
    warnings: int = 0
    commands: int = 0
    coalesced: int = 0  # ticks replaced by a newer one before their write (node/writer.py)
    tick_ms: list[float] = field(default_factory=list)  # the last 1,000 tick durations
    #: the last 1,000 waits of input for its tick: from the first pose that woke the loop to
    #: the start of the tick that applies it (the gap after the previous tick, or its end)
    wait_ms: list[float] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)
    window_ms: list[float] = field(default_factory=list)  # the newest ticks since take_window
    window_ticks: int = 0  # every tick since take_window, and the longest
    window_max_ms: float = 0.0
    window_overruns: int = 0
    window_start: float = field(default_factory=time.monotonic)
    last_window: str = ""

    def record(self, ms: float, overran: bool) -> None:
        """One tick's duration."""
        self.tick_ms.append(ms)
        del self.tick_ms[:-1000]
        self.window_ms.append(ms)
        self.window_ticks += 1
        self.window_max_ms = max(self.window_max_ms, ms)
        if len(self.window_ms) > 2 * WINDOW_TICKS:
            del self.window_ms[:-WINDOW_TICKS]
        self.worst_ms = max(self.worst_ms, ms)
        if overran:
            self.overruns += 1
            self.window_overruns += 1

    def record_wait(self, ms: float) -> None:
        """How long the input that woke the loop waited for its tick."""
        self.wait_ms.append(ms)
        del self.wait_ms[:-1000]

    def line(self, drops: str, *, window: bool = False) -> str:
        """The status line: uptime, ticks, overruns, ``drops`` per topic and field, warnings,
        how long input waited for its tick (p50, p99 of the last 1,000 ticks it woke), and the
        window since the previous windowed line (``window=True`` starts a new one) or the last
        one taken."""
        line = (
            f"status: up {time.monotonic() - self.started:.0f} s, {self.ticks} ticks, "
            f"{self.overruns} overruns, drops {drops}, {self.warnings} warnings"
        )
        if self.coalesced:
            line += f", {self.coalesced} ticks written with the next"
        if self.wait_ms:
            waits = sorted(self.wait_ms)
            p50, p99 = (waits[min(len(waits) - 1, int(p * len(waits)))] for p in (0.5, 0.99))
            line += f", input waits p50 {p50:.1f} ms, p99 {p99:.1f} ms"
        last = self.take_window() if window else self.last_window
        return f"{line}; {last}" if last else line

    def take_window(self, now: float | None = None) -> str:
        """``"window N s: K ticks, p50 X ms, p99 Y ms, max Z ms, O overruns"`` since the
        previous call (percentiles over its newest WINDOW_TICKS ticks); starts a new one."""
        now = time.monotonic() if now is None else now
        ms = sorted(self.window_ms)

        def pct(p: float) -> float:
            return ms[min(len(ms) - 1, int(p * len(ms)))] if ms else 0.0

        line = (
            f"window {now - self.window_start:.0f} s: {self.window_ticks} ticks, "
            f"p50 {pct(0.5):.1f} ms, p99 {pct(0.99):.1f} ms, max {self.window_max_ms:.1f} ms, "
            f"{self.window_overruns} overruns"
        )
        self.window_ms, self.window_overruns, self.window_start = [], 0, now
        self.window_ticks, self.window_max_ms = 0, 0.0
        self.last_window = line
        return line
