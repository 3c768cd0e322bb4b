"""Which facts a plot shows: the most relevant ones, at most ``max_facts``, so that a picture
stays readable (and quick to draw) whatever the size of the database.

Relevance, most relevant first (:func:`ranked`):

1. facts where an agent holds a false belief (a value the reference agent does not share);
2. facts the reference agent (the robot) holds at some time in the window;
3. facts that change most in the window (changes of value or confidence of every agent,
   plus changes of their numbers);
4. then the fact that starts first, then by name.

The facts kept are drawn in their usual (name) order, not in the order of relevance.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

from toaster.errors import InvalidInputError
from toaster.outputs.plotting.timeline import FALSE_BELIEF, Lane, Timeline

#: Facts a plot shows by default (``max_facts``; None or 0: all).
MAX_FACTS = 20


class Selection(NamedTuple):
    """The timeline to draw, how many facts matched (``total``) and how many of them are
    not drawn (``left_out``)."""

    timeline: Timeline
    total: int
    left_out: int = 0


def check_max_facts(max_facts: int | None) -> int | None:
    """``max_facts`` (0 and None: no cap); a negative one raises a one-line error."""
    if max_facts is not None and max_facts < 0:
        msg = f"max facts {max_facts} is negative: give a positive number (0 = every fact)"
        raise InvalidInputError(msg)
    return max_facts or None


def ranked(timeline: Timeline, lanes: list[Lane] | None = None) -> list[Lane]:
    """The facts of ``timeline`` (or ``lanes`` of it), most relevant first (see the module's
    docstring)."""
    false = {d.lane for d in timeline.divergences if d.kind == FALSE_BELIEF}

    def key(lane: Lane) -> tuple[bool, bool, int, int, str]:
        held_by_reference = any(
            c.value is not None
            for s in lane.series
            if s.agent == timeline.reference
            for c in s.changes
        )
        changes = sum(len(s.changes) - 1 for s in lane.series)
        changes += sum(len(sig.points) - 1 for sig in lane.signals)
        starts = [c.t_ns for s in lane.series for c in s.changes if c.value is not None]
        return (
            lane.label not in false,
            not held_by_reference,
            -changes,
            min(starts, default=timeline.until_ns),
            lane.label,
        )

    return sorted(timeline.lanes if lanes is None else lanes, key=key)


def select_facts(
    timeline: Timeline, max_facts: int | None = MAX_FACTS, *, numbers_only: bool = False
) -> Selection:
    """Keep the ``max_facts`` most relevant facts of ``timeline`` (all with 0 or None);
    with ``numbers_only``, among the facts that carry numbers."""
    cap = check_max_facts(max_facts)
    candidates = timeline.number_lanes if numbers_only else timeline.lanes
    total = len(candidates)
    if cap is None or total <= cap:
        return Selection(timeline, total)
    kept = {id(lane) for lane in ranked(timeline, candidates)[:cap]}
    lanes = [lane for lane in timeline.lanes if id(lane) in kept]
    labels = {lane.label for lane in lanes}
    divergences = [d for d in timeline.divergences if d.lane in labels]
    return Selection(replace(timeline, lanes=lanes, divergences=divergences), total, total - cap)
