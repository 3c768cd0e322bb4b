"""A Foxglove recording: one MCAP file holding the live server's channels and schemas
(:mod:`toaster.outputs.foxglove`), written by :func:`toaster.outputs.recording.record` through
:class:`FoxgloveRecorder` (``toaster run --record FILE.mcap --record-format foxglove``)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from toaster.errors import InvalidInputError
from toaster.model import EventRow, Fact, FactRow
from toaster.outputs.foxglove import (
    BELIEFS_TOPIC,
    FACTS_TOPIC,
    HEALTH_TOPIC,
    Channels,
    beliefs_message,
    facts_message,
    health_message,
)
from toaster.outputs.recording.input import area_spec, entity_poses
from toaster.outputs.recording.msgs import Scene


def check_path(path: str | Path) -> Path:
    """A new ``.mcap`` file in an existing folder."""
    path = Path(path)
    if path.suffix != ".mcap":
        msg = f"cannot record Foxglove channels into {str(path)!r}: give a FILE.mcap name"
        raise InvalidInputError(msg)
    if path.exists():
        msg = f"cannot record into {str(path)!r}: it exists; give a new file name"
        raise InvalidInputError(msg)
    if not path.parent.is_dir():
        msg = f"cannot record into {str(path)!r}: folder {str(path.parent)!r} does not exist"
        raise InvalidInputError(msg)
    return path


class FoxgloveRecorder:
    """Writes frames, fact lists, beliefs and events as the live Foxglove server publishes
    them (the interface of :class:`toaster.outputs.recording.Recorder`)."""

    def __init__(self, path: str | Path, *, frame_id: str = "map", **_ignored: Any) -> None:
        self.path = self.mcap_path = check_path(path)
        self.frame_id = frame_id
        self.scene = Scene(frame_id)
        self.areas: dict[str, dict[str, Any]] = {}
        self._area_facts: list[Fact] = []
        self._motion: list[Fact] = []
        self._agent = ""
        self._truth: list[Any] | None = None
        self._pending: tuple[int, list[tuple[str, list[Any], bool]]] = (-1, [])
        self.frames = self.facts = self.fact_lists = self.beliefs = 0

    def __enter__(self) -> FoxgloveRecorder:
        import foxglove

        self.context = foxglove.Context()
        self.channels = Channels(self.context)
        self.writer = foxglove.open_mcap(self.path, context=self.context)
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        self._flush_beliefs()
        self.writer.close()
        if exc_type is not None:
            self.path.unlink(missing_ok=True)

    def write_run(self, info: Any) -> None:
        """Not a Foxglove channel: a Foxglove recording does not replay as toaster input."""

    def write_world(self, t_ns: int, fields: Mapping[str, Any]) -> None:
        """Not a Foxglove channel (as :meth:`write_run`)."""

    def write_frame(
        self, t_ns: int, entities: Iterable[Any], areas: Iterable[Any] | None = None
    ) -> None:
        """The scene, areas, motion and /tf at ``t_ns``; with ``areas``, replace the areas."""
        self._flush_beliefs()
        self.scene.update(t_ns, entity_poses(entities))
        if areas is not None:
            self.areas = dict(area_spec(item) for item in areas)
        world = self.scene.world
        self.channels.frame(t_ns, world, self.areas, self._area_facts, self._motion)
        self.frames += 1
        status = f"recorded: frame {self.frames}"  # no node: ticks are the recording's frames
        self.channels.put(HEALTH_TOPIC, health_message(t_ns, ticks=self.frames, status=status))

    def write_fact_list(self, t_ns: int, source: str, facts: Iterable[Fact | FactRow]) -> None:
        """The self agent's facts of producer ``source`` at ``t_ns``."""
        self._flush_beliefs(t_ns)
        rows = list(facts)
        self._agent = next((r.agent_id for r in rows if isinstance(r, FactRow)), self._agent)
        self.channels.put(FACTS_TOPIC, facts_message(t_ns, self._agent, source, rows))
        held = [r if isinstance(r, Fact) else r.to_fact() for r in rows]
        if source == "area_manager":
            self._area_facts = held
        elif source == "agent_monitor":
            self._motion = held
        self.fact_lists += 1

    def write_beliefs(
        self, t_ns: int, holder: str, facts: Iterable[Fact | FactRow], *, is_self: bool = False
    ) -> None:
        """What ``holder`` believes at ``t_ns``; written once every holder's set at that time
        is known, so that false beliefs compare with the self agent's at the same time."""
        self._flush_beliefs(t_ns)
        self._pending[1].append((holder, list(facts), is_self))
        self._pending = (t_ns, self._pending[1])

    def _flush_beliefs(self, before: int | None = None) -> None:
        t_ns, pending = self._pending
        if not pending or (before is not None and before == t_ns):
            return
        for _holder, facts, is_self in pending:
            if is_self:
                self._truth = facts
        for holder, facts, is_self in pending:
            message = beliefs_message(t_ns, holder, facts, self._truth, is_self=is_self)
            self.channels.put(BELIEFS_TOPIC, message)
            self.beliefs += 1
        self._pending = (-1, [])

    def write_event(self, event: EventRow) -> None:
        """One belief change on /toaster/events and /toaster/log."""
        self._flush_beliefs()
        self.channels.event(event)
        self.facts += 1

    def write_fact_line(self, t_ns: int, text: str, *, name: str = "toaster") -> None:
        """Not used by :func:`record` for Foxglove recordings."""
