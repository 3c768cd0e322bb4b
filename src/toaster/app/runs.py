"""Running an input file through the producers into a database: what ``toaster run`` does.

:func:`run_file` loads a scenario, track recording or ROS bag (:func:`toaster.producers.
load_session`), registers its entities and areas, ticks it (optionally paced to the wall
clock) and, when asked, writes the run as a rosbag2/MCAP recording. Every check that can
fail (the recording folder, the optional extras, the rate, the input file) happens before the
first write.

Ticks (:func:`tick_times`): a recording or track file ticks on its own sample times, so that
every sample is answered at its own time (the facts' times are the samples'); a scenario, or
any input run with a rate, ticks on a fixed grid from its start. A toaster recording replays
the run that made it (:mod:`toaster.app.replay`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from toaster.errors import InvalidInputError

if TYPE_CHECKING:
    from toaster.app.published import RunNode
    from toaster.db import Database
    from toaster.producers import Session, Stats

#: ``progress(ticks_done, ticks_total)``, called after every tick
Progress = Callable[[int, int], None]
#: ``live(node)``: start outputs on the run's node (:mod:`toaster.app.published`), stopped
#: when the context ends
Live = Callable[["RunNode"], AbstractContextManager[Any]]


@dataclass(frozen=True)
class RunReport:
    """What a run did: its ticks and facts (``stats``), the input time it covered, the wall
    time it took, and the recording it wrote (``toaster.outputs.recording.RecordingResult``) if
    any."""

    name: str
    stats: Stats
    input_s: float
    wall_s: float
    recording: Any = None
    notes: tuple[str, ...] = ()


def needed_extras(
    path: str | Path, record_dir: str | Path | None = None, record_format: str = "ros"
) -> list[tuple[str, str]]:
    """The optional extras a run of ``path`` needs, as ``(extra, feature)``: reading a ROS bag
    and writing a recording need ``rosbag`` (a Foxglove recording ``foxglove``)."""
    from toaster.world.bags import is_bag

    needs = []
    if is_bag(Path(path)):
        needs.append(("rosbag", f"running the bag {Path(path).name}"))
    if record_dir is not None:
        extra = "foxglove" if record_format == "foxglove" else "rosbag"
        needs.append((extra, f"run --record-format {record_format}"))
    return needs


def check_run(
    path: str | Path,
    *,
    record_dir: str | Path | None = None,
    rate_hz: float | None = None,
    record_format: str = "ros",
) -> float | None:
    """Refuse what would fail later, before anything is read or written: a recording folder
    that exists, a missing extra, a bad rate. Returns the checked rate."""
    from toaster.extras import require
    from toaster.timeutil import check_rate

    if record_dir is not None and record_format == "foxglove":
        from toaster.outputs.foxglove.record import check_path

        check_path(record_dir)
    elif record_dir is not None and Path(record_dir).exists():
        msg = f"cannot record into {str(record_dir)!r}: it exists; give a new folder name"
        raise InvalidInputError(msg)
    for extra, feature in needed_extras(path, record_dir, record_format):
        require(extra, feature)
    return None if rate_hz is None else check_rate(rate_hz, "--rate")


def tick_times(session: Session, end_ns: int, rate_hz: float | None = None) -> np.ndarray:
    """When a run of ``session`` ticks, up to ``end_ns``.

    With ``rate_hz``, or for an input without samples of its own (a scenario), a fixed grid
    from the start. Else the input's own sample times (``source.sample_times()``: a track file's
    or bag's perception stamps, a toaster recording's ticks), so that no sample waits for the
    next grid point and is answered from the one before; through a gap longer than 1.5 steps
    of the input's rate, ticks at that rate fill in (timeouts such as ``presence_timeout``
    still pass while nothing is perceived).
    """
    from toaster.timeutil import NS_PER_S, check_rate

    start = session.start_ns
    samplers = [getattr(s, "sample_times", None) for s in session.sources]
    step = round(NS_PER_S / check_rate(rate_hz or session.rate_hz))
    if rate_hz is not None or not samplers or None in samplers:
        return np.arange(start, end_ns + 1, step, dtype=np.int64)
    times = np.unique(np.concatenate([np.asarray(f(), np.int64) for f in samplers if f]))
    times = times[(times >= start) & (times <= end_ns)]
    if not len(times) or times[0] != start:
        times = np.concatenate([[start], times])
    gaps = np.flatnonzero(np.diff(times) > 1.5 * step)
    fill = [
        np.arange(times[k] + step, times[k + 1] - step // 2, step, dtype=np.int64) for k in gaps
    ]
    return np.unique(np.concatenate([times, *fill])) if fill else times


def run_file(
    path: str | Path,
    db: Database | None = None,
    *,
    rate_hz: float | None = None,
    until_ns: int | None = None,
    realtime: bool = False,
    fps: float | None = None,
    holders: str | None = None,
    config: Mapping[str, Any] | None = None,
    tf_map: str | Path | None = None,
    pose_topics: Mapping[str, tuple[str, str]] | None = None,
    record_dir: str | Path | None = None,
    progress: Progress | None = None,
    record_format: str = "ros",
    live: Live | None = None,
    wait: bool = False,
    stop: threading.Event | None = None,
) -> RunReport:
    """Tick ``path`` into ``db`` (None: compute only) and report what happened.

    Args:
        rate_hz: ticks per second on a fixed grid (default: a recording's or track file's own
            sample times, a scenario's rate; :func:`tick_times`).
        until_ns: stop after this much input time (from the input's start).
        realtime: pace the ticks to the wall clock.
        fps, holders, config, tf_map, pose_topics: as :func:`toaster.producers.load_session`.
        record_dir: also write the run as a rosbag2/MCAP recording in this new folder, or as
            a ROS 1 bag for a ``.bag`` name (:mod:`toaster.outputs.recording`; needs
            ``toaster[rosbag]``), with what replays it whole (``/toaster/run``,
            ``/toaster/world``); ``record_format`` ``foxglove``: a ``FILE.mcap`` of the
            live Foxglove server's channels instead (needs ``toaster[foxglove]``).
        progress: called after each tick with (ticks done, ticks in all).
        live: publish the ticks: ``live(node)`` starts outputs on the run's
            :class:`~toaster.app.published.RunNode` (as ``toaster serve`` starts them on its
            node) and is left at the end; ``wait``: tick only once someone subscribes.
        stop: once set, the run stops between two ticks (what ran is stored and recorded).

    Areas stored in ``db`` are added to the file's, and the file's are stored; the same input
    into a fresh database gives the same facts and events. A toaster recording replays the run
    that made it (:mod:`toaster.app.replay`): the same facts, events and beliefs.
    """
    from toaster.app import replay
    from toaster.producers import Runner, load_session
    from toaster.world.recorded import world_fields

    path = Path(path)
    rate_hz = check_run(path, record_dir=record_dir, rate_hz=rate_hz, record_format=record_format)
    store = db.store() if db is not None else None
    session = load_session(
        path,
        store.areas() if store is not None else None,
        fps=fps,
        holders=holders,
        config=config,
        tf_map=tf_map,
        pose_topics=pose_topics,
    )
    session = replay.as_recorded(session, holders=holders, config=config)
    notes = replay.old_recording_note(path, session)
    end = session.end_ns if until_ns is None else min(session.end_ns, session.start_ns + until_ns)
    runner = Runner(
        session.world,
        session.sources,
        session.producers,
        store=store,
        agent_id=session.self_id,
        config=session.config,
    )
    if db is not None and store is not None:
        notes += replay.apply_settings(session, db)
        session.register(store)
    times = tick_times(session, end, rate_hz)
    frames: list[tuple[Any, ...]] = []
    world: list[tuple[int, dict[str, Any]]] = []
    done, last = 0, session.start_ns
    stop = stop or threading.Event()

    def on_tick(t_ns: int) -> None:
        nonlocal done, last
        if node is not None:
            node.ticked(t_ns)
        if record_dir is not None:
            frames.append(session.frame(t_ns, with_areas=not frames))
            world.append((t_ns, world_fields(session.world, t_ns)))
        done, last = done + 1, t_ns
        if progress is not None:
            progress(done, len(times))

    node: RunNode | None = None
    wall = time.perf_counter()
    if live is None:
        runner.run_at(times.tolist(), realtime=realtime, on_tick=on_tick, stop=stop)
    else:
        from toaster.app.published import RunNode

        node = RunNode(db, session, runner)
        try:
            with live(node):
                if wait and node.wait_for_subscriber(stop):
                    wall = time.perf_counter()
                runner.run_at(
                    times.tolist(),
                    realtime=realtime,
                    on_tick=on_tick,
                    computed=node.computed,
                    stop=stop,
                    write_behind=node.write_behind,
                )
        finally:
            node.close()
    wall_s = time.perf_counter() - wall
    if done < len(times):
        notes.append(f"stopped after {done} of {len(times)} ticks")
        end = last
    recording = None
    if record_dir is not None:
        from toaster.outputs.recording import record

        info = replay.run_info(session, db, end, rate_hz or session.rate_hz)
        recorder: Any = None
        if record_format == "foxglove":
            from toaster.outputs.foxglove.record import FoxgloveRecorder

            recorder = FoxgloveRecorder
        recording = record(record_dir, frames, db=db, run=info, world=world, recorder=recorder)
    return RunReport(
        path.name,
        runner.stats,
        (end - session.start_ns) / 1e9,
        wall_s,
        recording,
        tuple(notes),
    )
