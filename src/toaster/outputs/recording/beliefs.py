"""Belief channels of a recording (helpers of :mod:`toaster.outputs.recording`): what each belief
holder
holds, as typed messages on a topic of its own, so that a viewer shows Sally's world beside
the robot's.

One topic per holder, ``/toaster/beliefs/<AGENT>`` (nested holders as a path: ``ANNE>SALLY``,
what Anne thinks Sally believes, on ``/toaster/beliefs/ANNE/SALLY``), of type
``toaster_recording/msg/Beliefs`` (:data:`BELIEFS_MSG`): the holder's complete set of facts,
not a delta, at the first frame and whenever it changed. The definition travels in the bag.
Each agent of the chain is one name token (:func:`toaster.quoting.ros_name`); the message's
``holder`` and ``chain`` keep the exact ids.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

from toaster.errors import InvalidInputError
from toaster.model import FactRow, NumberedInterval
from toaster.outputs.recording.msgs import FactTimeline
from toaster.quoting import ros_name

if TYPE_CHECKING:
    from toaster.db.database import Database

BELIEFS_TOPIC = "/toaster/beliefs"
BELIEFS_TYPE = "toaster_recording/msg/Beliefs"
BELIEFS_MSG = """\
# Everything one belief holder holds at header.stamp: the complete set, not a delta.
std_msgs/Header header
# The holder: an agent (SALLY) or a nested holder (ANNE>SALLY: what ANNE thinks SALLY believes).
string holder
# The same holder as a chain of agents, outermost first: [ANNE, SALLY].
string[] chain
# True for the self agent (the robot), whose beliefs are the world as toaster sees it.
bool is_self
# Each fact: time = this message's time, timeStart = when the holder came to believe it.
toaster_msgs/Fact[] facts
"""


def chain(holder: str) -> list[str]:
    """A holder as its chain of agents: ``ANNE>SALLY`` → ``[ANNE, SALLY]``."""
    from toaster.rules.hook import SEPARATOR

    return holder.split(SEPARATOR)


def holder_topic(holder: str) -> str:
    """The topic of ``holder``'s beliefs: one name token per agent of its chain
    (:func:`~toaster.quoting.ros_name`, injective: two holders never share a topic)."""
    return "/".join([BELIEFS_TOPIC, *(ros_name(part) for part in chain(holder))])


class BeliefTimeline:
    """The holders of a window (each agent, self included, and every nested holder with facts),
    whether each is the self agent, and their intervals as snapshots over time."""

    def __init__(
        self, holders: dict[str, bool], rows: Iterable[FactRow | NumberedInterval]
    ) -> None:
        self.is_self = holders
        self.timeline = FactTimeline(rows, key="agent_id", groups=sorted(holders))

    @classmethod
    def from_db(
        cls, db: Database, agent: str | Sequence[str] | None, since: int | None, until: int | None
    ) -> BeliefTimeline:
        """The intervals of ``agent`` (ids, exact; default every holder) that overlap the
        window, followed periods included (as ``fact_history`` shows them)."""
        from toaster import queries

        agents = {a.id: a.is_self for a in queries.agents(db)}
        wanted = [agent] if isinstance(agent, str) else (None if agent is None else list(agent))
        rows = queries.numbered_history(db, wanted, since=since, until=until)
        for name in wanted or ():
            if name not in agents and not queries.history(db, name, limit=1):
                msg = (
                    f"unknown agent {name!r}: give an agent (toaster get-info AGENT) or a "
                    "nested holder with beliefs (ANNE>SALLY)"
                )
                raise InvalidInputError(msg)
        names = wanted if wanted is not None else [*agents, *(r.row.agent_id for r in rows)]
        return cls({name: agents.get(name, False) for name in names}, rows)

    def boundaries(self) -> list[int]:
        """Every time a belief started or ended."""
        return self.timeline.boundaries()

    def snapshots(self, times: Sequence[int]) -> Any:
        """(t, holder, facts held at t) at the first time and whenever they changed."""
        return self.timeline.snapshots(times)
