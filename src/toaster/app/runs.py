"""Running an input file through the producers into a database: what ``toaster run`` does.

:func:`run_file` loads a scenario, track recording or ROS bag (:func:`toaster.producers.
load_session`), registers its entities and areas, ticks it (optionally paced to the wall
clock) and, when asked, writes the run as a rosbag2/MCAP recording. Every check that can
fail (the recording folder, the optional extras, the rate, the input file) happens before the
first write.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from toaster.errors import InvalidInputError

if TYPE_CHECKING:
    from toaster.db import Database
    from toaster.producers import Stats

#: ``progress(ticks_done, ticks_total)``, called after every tick
Progress = Callable[[int, int], None]


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


def needed_extras(path: str | Path, record_dir: str | Path | None = None) -> list[tuple[str, str]]:
    """The optional extras a run of ``path`` needs, as ``(extra, feature)``: reading a ROS bag
    and writing a recording need ``rosbag``."""
    from toaster.world.bags import is_bag

    needs = []
    if is_bag(Path(path)):
        needs.append(("rosbag", f"running the bag {Path(path).name}"))
    if record_dir is not None:
        needs.append(("rosbag", "run --record"))
    return needs


def check_run(
    path: str | Path, *, record_dir: str | Path | None = None, rate_hz: float | None = None
) -> float | None:
    """Refuse what would fail later, before anything is read or written: a recording folder
    that exists, a missing extra, a bad rate. Returns the checked rate."""
    from toaster.extras import require
    from toaster.timeutil import check_rate

    if record_dir is not None and Path(record_dir).exists():
        msg = f"cannot record into {str(record_dir)!r}: it exists; give a new folder name"
        raise InvalidInputError(msg)
    for extra, feature in needed_extras(path, record_dir):
        require(extra, feature)
    return None if rate_hz is None else check_rate(rate_hz, "--rate")


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
) -> RunReport:
    """Tick ``path`` into ``db`` (None: compute only) and report what happened.

    Args:
        rate_hz: ticks per second (default: the file's own rate).
        until_ns: stop after this much input time (from the input's start).
        realtime: pace the ticks to the wall clock.
        fps, holders, config, tf_map, pose_topics: as :func:`toaster.producers.load_session`.
        record_dir: also write the run as a rosbag2/MCAP recording in this new folder, or as
            a ROS 1 bag for a ``.bag`` name (:mod:`toaster.outputs.recording`; needs
            ``toaster[rosbag]``).
        progress: called after each tick with (ticks done, ticks in all).

    Areas stored in ``db`` are added to the file's, and the file's are stored; the same input
    into a fresh database gives the same facts and events.
    """
    from toaster.producers import Runner, load_session

    path = Path(path)
    rate_hz = check_run(path, record_dir=record_dir, rate_hz=rate_hz)
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
    end = session.end_ns if until_ns is None else min(session.end_ns, session.start_ns + until_ns)
    runner = Runner(
        session.world,
        session.sources,
        session.producers,
        store=store,
        agent_id=session.self_id,
        config=session.config,
    )
    if store is not None:
        session.register(store)
    hz = rate_hz or session.rate_hz
    total = max(1, int((end - session.start_ns) * hz / 1e9) + 1)
    frames: list[tuple[Any, ...]] = []
    done = 0

    def on_tick(t_ns: int) -> None:
        nonlocal done
        if record_dir is not None:
            frames.append(session.frame(t_ns, with_areas=not frames))
        done += 1
        if progress is not None:
            progress(done, total)

    wall = time.perf_counter()
    runner.run(session.start_ns, end, hz, realtime=realtime, on_tick=on_tick)
    wall_s = time.perf_counter() - wall
    recording = None
    if record_dir is not None:
        from toaster.outputs.recording import record

        recording = record(record_dir, frames, db=db)
    return RunReport(path.name, runner.stats, (end - session.start_ns) / 1e9, wall_s, recording)
