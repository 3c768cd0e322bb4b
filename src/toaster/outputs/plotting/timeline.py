"""Fact timelines: the step function of one or several facts, per agent, over a time window.

Built from the stored validity intervals (current facts and memory), never sampled: a series
holds one :class:`Change` per change of value (or confidence), starting with the value held at
the window start. Where an agent's value differs from the reference agent's (the robot, i.e.
the ``is_self`` agent, when it is plotted) the timeline records a :class:`Divergence`.

Facts that carry a number (``value_num``: a distance, a speed, an angle) also get, per agent,
a :class:`Signal`: the step function of that number from :func:`toaster.queries.signal`, with
every refresh beyond the property's tolerance (``fact_samples``), not only the interval's last
number, and ``None`` where the fact does not hold.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import TYPE_CHECKING, Any, NamedTuple

from toaster.errors import InvalidInputError, UnknownAgentError
from toaster.model import FactKey, FactRow, check_list, check_text, listed, shown
from toaster.timeutil import TimeFrame, check_optional_ns, format_ns

if TYPE_CHECKING:
    from toaster.db.database import Database

#: Divergence kinds: the agent holds a value the reference does not share, or holds nothing
#: while the reference holds a value.
FALSE_BELIEF = "false_belief"
UNAWARE = "unaware"

#: What to draw or write of the numbers: bars and number lines (``both``), number lines of the
#: facts that carry numbers only (``only``), or the bars only (``off``).
NUMBERS = ("both", "only", "off")

#: Units of ``value_num`` by property or (property, sub_property) (see docs/producers.md).
UNITS: dict[str | tuple[str, str], str] = {
    "Distance": "m",
    "IsMoving": "m/s",
    ("IsMovingToward", "distance"): "m",
    "IsLookingToward": "rad",
    "IsLookingAt": "rad",
    "IsFacing": "rad",
    "IsNextTo": "m",
    "IsReachableBy": "m",
    "CanReach": "m",
}


class Change(NamedTuple):
    """From ``t_ns`` on (until the next change), the agent holds ``value`` (None: nothing)."""

    t_ns: int
    value: str | None
    value_num: float | None
    confidence: float | None
    level: int  # 0 = not believed, k = the lane's k-th distinct value (1-based)


def _in_force(steps: list[Any], t_ns: int) -> Any:
    """The last of time-sorted ``steps`` (each with ``t_ns``) at or before ``t_ns``, else the
    first."""
    current = steps[0]
    for step in steps:
        if step.t_ns > t_ns:
            break
        current = step
    return current


class Series(NamedTuple):
    """The step function of one fact as one agent believed it."""

    agent: str
    changes: list[Change]

    def value_at(self, t_ns: int) -> Change:
        """The change in force at ``t_ns`` (the first one before the window start)."""
        return _in_force(self.changes, t_ns)


class Point(NamedTuple):
    """From ``t_ns`` on (until the next point), the number and its confidence (None: the fact
    does not hold, or holds no number)."""

    t_ns: int
    value_num: float | None
    confidence: float | None


class Signal(NamedTuple):
    """The number of one fact over time as one agent believed it: step points from the window
    start (the first point is the number held then, possibly None)."""

    agent: str
    points: list[Point]

    def value_at(self, t_ns: int) -> Point:
        """The point in force at ``t_ns`` (the first one before the window start)."""
        return _in_force(self.points, t_ns)

    def steps(
        self, since_ns: int, until_ns: int, axis: TimeFrame | None = None
    ) -> tuple[list[float], list[float]]:
        """x (seconds since the start of ``axis``, default ``since_ns``) and y (NaN where
        nothing is held) of a post-step line: one entry per point plus one closing entry at
        ``until_ns``."""
        nan = float("nan")
        axis = axis if axis is not None else TimeFrame(since_ns, "elapsed")
        xs = [axis.offset_s(p.t_ns) for p in self.points]
        ys = [nan if p.value_num is None else float(p.value_num) for p in self.points]
        return [*xs, axis.offset_s(until_ns)], [*ys, ys[-1] if ys else nan]


class Divergence(NamedTuple):
    """A span where ``agent`` believed ``value`` while ``reference`` believed another."""

    lane: str
    agent: str
    reference: str
    start_ns: int
    end_ns: int
    value: str | None
    reference_value: str | None
    kind: str


@dataclass
class Lane:
    """One fact (subject, property, target and owners), with one series per agent."""

    key: FactKey
    values: list[str]
    series: list[Series] = field(default_factory=list)
    signals: list[Signal] = field(default_factory=list)  # agents that held a number here

    @property
    def label(self) -> str:
        """``subject property target`` with owners and sub-property when they are set."""
        return fact_label(self.key)

    @property
    def unit(self) -> str | None:
        """The unit of the lane's numbers (:data:`UNITS`), None when unknown."""
        return number_unit(self.key)

    @property
    def number_label(self) -> str:
        """The y-axis label of the numbers: ``Distance (m)``, ``IsMovingToward/distance (m)``."""
        prop = (
            f"{self.key.property}/{self.key.sub_property}"
            if self.key.sub_property
            else self.key.property
        )
        unit = self.unit
        return f"{prop} ({unit})" if unit else prop


@dataclass
class Timeline:
    """Everything a plot or a data file needs, with times in integer nanoseconds."""

    since_ns: int
    until_ns: int
    agents: list[str]
    reference: str
    lanes: list[Lane]
    divergences: list[Divergence]
    #: the data's time frame (:meth:`toaster.db.Database.time_frame`); None: the window's
    frame: TimeFrame | None = None

    @property
    def axis(self) -> TimeFrame:
        """The frame of the time axis (x = :meth:`~toaster.timeutil.TimeFrame.offset_s`,
        seconds since the data's start), else one starting at the window start."""
        return self.frame if self.frame is not None else TimeFrame(self.since_ns, "elapsed")

    @property
    def number_lanes(self) -> list[Lane]:
        """The lanes whose facts carry numbers (with at least one :class:`Signal`)."""
        return [lane for lane in self.lanes if lane.signals]


def number_unit(key: FactKey) -> str | None:
    """The unit of ``key``'s ``value_num`` (metres, m/s, radians), None when unknown."""
    return UNITS.get((key.property, key.sub_property), UNITS.get(key.property))


def check_numbers(numbers: str) -> str:
    """``numbers`` if it is one of :data:`NUMBERS`, else a one-line error."""
    if numbers not in NUMBERS:
        msg = f"unknown numbers mode {numbers!r}: use one of {', '.join(NUMBERS)}"
        raise InvalidInputError(msg)
    return numbers


def panels(timeline: Timeline, numbers: str = "both") -> list[tuple[str, Lane]]:
    """What a picture draws (and a data file holds), top to bottom: ``("bars", lane)`` for a
    fact's values per agent, ``("numbers", lane)`` for its numbers (see :data:`NUMBERS`)."""
    check_numbers(numbers)
    out: list[tuple[str, Lane]] = []
    for lane in timeline.lanes:
        if numbers != "only":
            out.append(("bars", lane))
        if numbers != "off" and lane.signals:
            out.append(("numbers", lane))
    if not out:
        msg = (
            "no numbers among the matching facts (none has a value_num): plot them "
            "without --numbers only"
        )
        raise InvalidInputError(msg)
    return out


def holder_note(agent: str) -> str | None:
    """What a nested holder's name means (``ANNE>SALLY``: what ANNE thinks SALLY believes);
    None for an agent."""
    parts = agent.split(">")
    return None if len(parts) < 2 else "what " + " thinks ".join(parts) + " believes"


def legend_notes(timeline: Timeline) -> list[str]:
    """The words of a plot's legend: what the hatching, the dots and each ``A>B`` mean."""
    ref = timeline.reference
    notes = [
        f"false belief: holds a value {ref} (reference) does not",
        f"unaware: holds nothing while {ref} holds a value",
    ]
    return notes + [f"{a} = {holder_note(a)}" for a in timeline.agents if holder_note(a)]


def fact_label(key: FactKey) -> str:
    """A readable name for a fact key (``alice.rightHand IsMoving``, ``mug IsOn table``)."""
    subject, target = key.subject_id, key.target_id
    if key.subject_owner_id and key.subject_owner_id != subject:
        subject = f"{key.subject_owner_id}.{subject}"
    if key.target_owner_id and key.target_owner_id != target:
        target = f"{key.target_owner_id}.{target}"
    prop = f"{key.property}/{key.sub_property}" if key.sub_property else key.property
    return " ".join(part for part in (subject, prop, target) if part)


def _as_list(value: str | Sequence[str] | None, what: str = "filter") -> list[str] | None:
    """None, or the names ``value`` gives (one text, or a list of texts), checked."""
    if value is None:
        return None
    names = [value] if isinstance(value, str) else check_list(value, what)
    return [check_text(name, what) for name in names]


def check_agents(db: Database, agents: str | Sequence[str] | None) -> tuple[list[str], str]:
    """The agents to plot (default all; nested holders such as ``ANNE>SALLY`` when named) and
    the reference one; unknown names raise."""
    from toaster.beliefs.api import holders
    from toaster.queries import agents as list_agents

    known = list_agents(db)
    names = [a.id for a in known]
    wanted = _as_list(agents, "agent") or names
    nested = [h for h in holders(db) if h not in names]
    for name in wanted:
        if name not in names and name not in nested:
            msg = (
                f"unknown agent {shown(name)}: known agents are "
                f"{listed(names, none='none registered')}"
            )
            raise UnknownAgentError(msg)
    if not wanted:
        msg = "no agent to plot: register agents first (toaster set-info entity --kind robot)"
        raise InvalidInputError(msg)
    selves = [a.id for a in known if a.is_self and a.id in wanted]
    return wanted, (selves[0] if selves else wanted[0])


def build_timeline(
    db: Database,
    *,
    subject: str | Sequence[str] | None = None,
    property: str | Sequence[str] | None = None,
    target: str | Sequence[str] | None = None,
    agents: str | Sequence[str] | None = None,
    since: int | None = None,
    until: int | None = None,
    reference: str | None = None,
    numbers: bool = True,
    frame: TimeFrame | None = None,
) -> Timeline:
    """Read the matching intervals and turn them into a :class:`Timeline`.

    ``since``/``until`` default to the first and last time found in the matching intervals.
    ``reference`` (default: the robot, else the first agent) is whose beliefs the others are
    compared with. Agents named in ``agents`` get a row in every lane; by default a lane shows
    only the agents concerned (see :func:`timeline_from_rows`). With ``numbers`` (default)
    the lanes whose facts carry numbers get their :class:`Signal` per agent (see
    :func:`add_signals`). Its time axis counts from the data's start (``frame``, default
    ``db.time_frame()``).
    """
    from toaster.queries import history

    names, default_ref = check_agents(db, agents)
    since, until = check_optional_ns(since, "since"), check_optional_ns(until, "until")
    if reference is not None and reference not in names:
        msg = f"reference agent {reference!r} is not plotted: add it to the agents ({names})"
        raise InvalidInputError(msg)
    if since is not None and until is not None and until <= since:
        msg = (
            f"empty time window: until {format_ns(until)} is not after since "
            f"{format_ns(since)}; give a later --until"
        )
        raise InvalidInputError(msg)
    rows = history(
        db,
        names,
        since=since,
        until=until,
        subject=_as_list(subject),
        property=_as_list(property),
        target=_as_list(target),
    )
    if not rows:
        wanted = ", ".join(
            f"{k}={v!r}"
            for k, v in (("subject", subject), ("property", property), ("target", target))
            if v is not None
        )
        msg = (
            f"no fact matches {wanted or 'the filters'} for {', '.join(names)} in the window;"
            " check the names with toaster get-info facts"
        )
        raise InvalidInputError(msg)
    since, until = _window(rows, since, until)
    timeline = timeline_from_rows(
        rows, since, until, names, reference or default_ref, show_all=agents is not None
    )
    timeline.frame = frame if frame is not None else db.time_frame()
    if numbers:
        add_signals(
            db,
            timeline,
            subject=_as_list(subject),
            property=_as_list(property),
            target=_as_list(target),
        )
    return timeline


def add_signals(db: Database, timeline: Timeline, **filters: Any) -> None:
    """Give each lane of ``timeline`` the :class:`Signal` of every plotted agent that held a
    number there, read with :func:`toaster.queries.signal` (``filters``: subject, property,
    target, as for the timeline) and clipped to the window."""
    from toaster.queries import signal

    def read(**more: Any) -> dict[tuple[str, ...], list[Any]]:
        found: dict[tuple[str, ...], list[Any]] = {}
        for point in signal(
            db, timeline.agents, since=timeline.since_ns, until=timeline.until_ns, **filters, **more
        ):
            found.setdefault(tuple(point[:5]), []).append(point)
        return found

    def short(key: FactKey) -> tuple[str, ...]:  # a signal point's key lacks the owners
        return (key.subject_id, key.property, key.sub_property, key.target_id)

    counts: dict[tuple[str, ...], int] = {}
    for lane in timeline.lanes:
        counts[short(lane.key)] = counts.get(short(lane.key), 0) + 1
    everything = read()
    for lane in timeline.lanes:
        points = everything
        if counts[short(lane.key)] > 1:  # keys that differ by their owners only: one query each
            points = read(
                subject_owner=lane.key.subject_owner_id, target_owner=lane.key.target_owner_id
            )
        for series in lane.series:
            held = points.get((series.agent, *short(lane.key)), [])
            clipped = signal_points(held, timeline.since_ns, timeline.until_ns)
            if any(p.value_num is not None for p in clipped):
                lane.signals.append(Signal(series.agent, clipped))
                _numbers_then(series, lane.signals[-1])


def _numbers_then(series: Series, signal: Signal) -> None:
    """A change's ``value_num`` is its interval's last stored number: make it the number held
    at the change's time (the interval may have been refreshed since)."""
    for i, change in enumerate(series.changes):
        if change.value is not None:
            series.changes[i] = change._replace(value_num=signal.value_at(change.t_ns).value_num)


def signal_points(points: Iterable[Any], since: int, until: int) -> list[Point]:
    """Step points (anything with ``t_ns``, ``value_num``, ``confidence``, in time order)
    clipped to ``[since, until)``: the first is the number held at ``since`` (None if none);
    at one instant the last point wins; repeats of the same number and confidence are dropped."""
    out = [Point(since, None, None)]
    for point in points:
        t_ns = max(point.t_ns, since)
        if t_ns >= until:
            break
        value = point.value_num
        new = Point(t_ns, value, None if value is None else point.confidence)
        if out and out[-1].t_ns == t_ns:
            out.pop()  # a later point at the same instant wins (an end, then the next start)
        if out and (out[-1].value_num, out[-1].confidence) == (new.value_num, new.confidence):
            continue
        out.append(new)
    return out


def _window(rows: Sequence[FactRow], since: int | None, until: int | None) -> tuple[int, int]:
    starts = [r.valid_from_ns for r in rows]
    ends = [r.valid_to_ns for r in rows if r.valid_to_ns is not None]
    lo = min(starts) if since is None else since
    if until is not None:
        return lo, until
    hi = max([*starts, *ends])
    if any(r.valid_to_ns is None for r in rows):  # show open intervals past their last change
        hi += max(1_000_000_000, (hi - lo) // 20)
    return lo, hi


def timeline_from_rows(
    rows: Iterable[FactRow],
    since: int,
    until: int,
    agents: Sequence[str],
    reference: str,
    *,
    show_all: bool = False,
) -> Timeline:
    """Build the timeline of ``rows`` (intervals of any agents) clipped to ``[since, until)``.

    A fact's lane shows the reference agent and the agents that held a fact with the same
    subject and property in the window (the others have no opinion on it), or every agent
    with ``show_all``.
    """
    grouped: dict[FactKey, dict[str, list[FactRow]]] = {}
    askers: dict[tuple[str, str], set[str]] = {}  # (subject, property) -> agents holding any
    for row in rows:
        key = FactKey(
            row.subject_id,
            row.subject_owner_id,
            row.property,
            row.sub_property,
            row.target_id,
            row.target_owner_id,
        )
        grouped.setdefault(key, {}).setdefault(row.agent_id, []).append(row)
        askers.setdefault((row.subject_id, row.property), set()).add(row.agent_id)
    lanes: list[Lane] = []
    for key in sorted(grouped):
        by_agent = grouped[key]
        values = sorted({r.value_text for rs in by_agent.values() for r in rs})
        lane = Lane(key, values)
        concerned = askers[(key.subject_id, key.property)] | {reference}
        for agent in agents:
            if show_all or agent in concerned:
                lane.series.append(
                    Series(agent, _changes(by_agent.get(agent, []), values, since, until))
                )
        lanes.append(lane)
    divergences = [d for lane in lanes for d in _divergences(lane, reference, until)]
    return Timeline(since, until, list(agents), reference, lanes, divergences)


def _changes(rows: list[FactRow], values: list[str], since: int, until: int) -> list[Change]:
    points: list[Change] = [Change(since, None, None, None, 0)]
    for row in sorted(rows, key=lambda r: r.valid_from_ns):
        start = max(row.valid_from_ns, since)
        end = until if row.valid_to_ns is None else min(row.valid_to_ns, until)
        if end <= start:
            continue
        points.append(
            Change(
                start,
                row.value_text,
                row.value_num,
                row.confidence,
                values.index(row.value_text) + 1,
            )
        )
        if end < until:
            points.append(Change(end, None, None, None, 0))
    out: list[Change] = []
    for point in points:
        if out and out[-1].t_ns == point.t_ns:
            out.pop()  # a later statement at the same instant wins (end then re-open)
        if out and (out[-1].value, out[-1].confidence) == (point.value, point.confidence):
            continue  # no visible change
        out.append(point)
    return out


def _divergences(lane: Lane, reference: str, until: int) -> list[Divergence]:
    ref = next(s for s in lane.series if s.agent == reference)
    out: list[Divergence] = []
    for series in lane.series:
        if series.agent == reference:
            continue
        cuts = sorted({c.t_ns for c in ref.changes} | {c.t_ns for c in series.changes} | {until})
        for start, end in pairwise(cuts):
            mine, theirs = series.value_at(start).value, ref.value_at(start).value
            if mine == theirs:
                continue
            kind = UNAWARE if mine is None else FALSE_BELIEF
            last = out[-1] if out else None
            if (
                last
                and last.agent == series.agent
                and last.end_ns == start
                and (last.value, last.reference_value, last.kind) == (mine, theirs, kind)
            ):
                out[-1] = last._replace(end_ns=end)
            else:
                out.append(
                    Divergence(lane.label, series.agent, reference, start, end, mine, theirs, kind)
                )
    return out
