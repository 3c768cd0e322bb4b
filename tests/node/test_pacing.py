"""The tick budget of a live node (toaster.node.pacing), on given times: input at the rate or
early never waits, two messages sent together both tick at once, and a flood is capped at
1.25 × the rate as the fixed gap capped it."""

from __future__ import annotations

import pytest

from toaster.node.pacing import FOLLOW_GAP, TickBudget

PERIOD = 1 / 30


def run(arrivals: list[float], tick_s: float = 0.005) -> list[float]:
    """Start times of the ticks the arrivals trigger (each tick takes ``tick_s``; input that
    comes while one runs waits for its end, as the node's loop does)."""
    budget = TickBudget(PERIOD, 0.0)
    starts: list[float] = []
    free = 0.0
    for at in arrivals:
        start = budget.ready_at(max(at, free))
        budget.take(start)
        starts.append(start)
        free = start + tick_s
    return starts


def test_input_at_the_rate_or_jittering_never_waits():
    steady = [k * PERIOD for k in range(100)]
    assert run(steady) == steady
    jitter = [k * PERIOD + (0.012 if k % 3 == 1 else 0.0) for k in range(100)]
    assert run(jitter) == jitter


def test_two_messages_after_a_stall_tick_at_once_and_a_third_waits():
    arrivals = [0.0, 0.2, 0.2, 0.2]
    starts = run(arrivals, tick_s=0.0)
    assert starts[:3] == [0.0, 0.2, 0.2]
    assert starts[3] == pytest.approx(0.2 + FOLLOW_GAP * PERIOD)


def test_a_flood_is_capped_at_one_and_a_quarter_of_the_rate():
    starts = run([k * 0.001 for k in range(3000)], tick_s=0.0)
    seconds = starts[-1] - starts[0]
    assert len(starts) / seconds == pytest.approx(1 / (FOLLOW_GAP * PERIOD), rel=0.01)
