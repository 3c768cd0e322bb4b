"""``toaster run`` (an input file into the store: :func:`toaster.app.runs.run_file`), ``toaster
area`` (areas kept in the database) and ``toaster relpos``."""

from __future__ import annotations

import contextlib
import functools
import json
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import click

from toaster.cli.checks import parse_duration_option
from toaster.cli.output import emit, listing_options
from toaster.cli.publish import check_publish, publish_options, published
from toaster.cli.rosopts import pose_topics as parse_pose_topics
from toaster.cli.rosopts import ros_input_options
from toaster.errors import InvalidInputError


@click.command("run")
@click.argument(
    "path", metavar="SCENARIO_OR_RECORDING", type=click.Path(exists=True, path_type=Path)
)
@click.option(
    "--rate",
    type=float,
    help="Ticks per second on a fixed grid (default: a recording's own sample times, a "
    "scenario's rate).",
)
@click.option("--until", "until", metavar="T", help="Stop after this much input time (20s).")
@click.option(
    "--realtime/--no-realtime",
    default=None,
    help="Pace ticks to the wall clock (default: when publishing: --foxglove, --ros2, --ros1).",
)
@click.option(
    "--fps",
    type=float,
    metavar="FPS",
    help="Frame rate of an obsmat file's frame "
    "numbers (default 25, as ETH/UCY); checked against its annotated velocities.",
)
@click.option(
    "--holders",
    metavar="none|humans|ID[,ID...]",
    help="Humans that hold beliefs "
    "(store agents). Default: a scenario's config belief_holders, else humans; none "
    "for recordings.",
)
@click.option(
    "--config",
    "config_file",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    metavar="FILE",
    help="Producer thresholds (YAML/JSON mapping, e.g. "
    "toward_range_humans: 3.6) laid over the file's own config.",
)
@ros_input_options
@click.option("--no-db", is_flag=True, help="Compute only; write nothing.")
@click.option(
    "--record",
    "record_dir",
    type=click.Path(path_type=Path),
    metavar="DIR",
    help="Also write the run as a rosbag2/MCAP recording in the new folder DIR, or "
    "as a ROS 1 bag if DIR ends in .bag (/tf, shapes, areas, pdg's entity "
    "lists, the producers' fact lists, each agent's beliefs, the facts' events; "
    "docs/recordings.md) for Foxglove, Lichtblick, RViz or `toaster run DIR`; "
    "needs toaster[rosbag].",
)
@click.option(
    "--record-format",
    type=click.Choice(["ros", "foxglove"]),
    default="ros",
    show_default=True,
    help="foxglove: --record FILE.mcap holds the channels of `toaster serve --foxglove` "
    "(docs/foxglove.md); needs toaster[foxglove].",
)
@publish_options(
    "Publish each tick on ROS 1 as `toaster serve --ros1` does, with /clock at the run's "
    "stamps (a roscore must run; docs/ros1.md).",
    "Publish each tick on ROS 2 over DDS as `toaster serve --ros2` does, with /clock at "
    "the run's stamps (toaster[ros2]; docs/ros2.md).",
)
@click.option(
    "--wait",
    is_flag=True,
    help="With --foxglove, --ros2 or --ros1: tick only once a client or reader subscribes.",
)
@click.pass_obj
def run(
    app: Any,
    path: Path,
    rate: float | None,
    until: str | None,
    realtime: bool | None,
    fps: float | None,
    holders: str | None,
    config_file: Path | None,
    tf_map: Path | None,
    pose_topics: tuple[str, ...],
    no_db: bool,
    record_dir: Path | None,
    record_format: str,
    ros1: bool,
    ros2: bool,
    domain_id: int | None,
    foxglove: int | None,
    wait: bool,
) -> None:
    """Tick a scenario (.yaml/.json), recording (obsmat .txt, .csv, .jsonl) or ROS bag
    (.bag, .mcap, .db3 or a rosbag2 folder) into the store.

    Areas stored in the database are added to the file's; the file's areas are stored.
    Same input into a fresh database gives the same facts and events.

    With --foxglove, --ros2 or --ros1 each tick is published as `toaster serve` publishes
    it, paced to the wall clock, stamped with the run's own times (a scenario starts at 0 s)
    and with the run's clock (Foxglove's server time, ROS's /clock); Ctrl-C or SIGTERM stops
    it between two ticks.
    """
    from toaster.app.runs import check_run, run_file
    from toaster.world.config import read_config_file

    check_publish(ros2=ros2, domain_id=domain_id)
    publishing = ros1 or ros2 or foxglove is not None
    if wait and not publishing:
        msg = "--wait waits for a subscriber: add --foxglove, --ros2 or --ros1"
        raise InvalidInputError(msg)
    realtime = publishing if realtime is None else realtime
    rate = check_run(path, record_dir=record_dir, rate_hz=rate, record_format=record_format)
    until_ns = None if until is None else parse_duration_option(until, "--until")
    config = read_config_file(config_file) if config_file is not None else None
    go = functools.partial(
        run_file,
        path,
        None if no_db else app.db,
        rate_hz=rate,
        until_ns=until_ns,
        realtime=realtime,
        fps=fps,
        holders=holders,
        config=config,
        tf_map=tf_map,
        pose_topics=parse_pose_topics(pose_topics),
        record_dir=record_dir,
        record_format=record_format,
    )
    if not publishing:
        _go(path, go)
        return
    from toaster.node.serve import stop_on_signals

    live = functools.partial(
        _publishing, ros1=ros1, ros2=ros2, domain_id=domain_id, foxglove=foxglove, wait=wait
    )
    with stop_on_signals() as stop:  # the run stops between two ticks, as serve does
        _go(path, functools.partial(go, live=live, wait=wait, stop=stop))


@contextlib.contextmanager
def _publishing(node: Any, **outputs: Any) -> Iterator[None]:
    """The run's outputs (cli/publish.py, as `toaster serve`'s), and what it says of them."""
    wait = outputs.pop("wait")
    with published(node, "toaster run", run=True, **outputs):
        if wait:
            click.echo("toaster run: waiting for a subscriber (Ctrl-C stops)", err=True)
        yield


def _go(path: Path, go: Callable[..., Any]) -> None:
    """Run, with a progress bar on a terminal, and report."""
    if sys.stderr.isatty():
        from rich.progress import Progress

        with Progress(transient=True) as bar:
            task = bar.add_task(path.name, total=None)
            _report(go(progress=lambda done, total: bar.update(task, completed=done, total=total)))
    else:
        _report(go())


def _report(report: Any) -> None:
    """The run's summary: ticks, speed, facts and events, time per stage, the recording."""
    stats, wall = report.stats, report.wall_s
    click.echo(
        f"{report.name}: {stats.ticks} ticks over {report.input_s:.1f} s of input in "
        f"{wall:.2f} s ({report.input_s / wall if wall else 0:.0f}× real time)"
    )
    click.echo(
        f"facts: {stats.facts} emitted; events: {stats.events} (appeared "
        f"{stats.appeared}, changed {stats.changed}, ended {stats.ended})"
    )
    for name, seconds in sorted(stats.seconds.items(), key=lambda kv: -kv[1]):
        click.echo(
            f"  {name:<14} {seconds * 1e3:9.1f} ms  "
            f"({seconds / max(stats.ticks, 1) * 1e3:.3f} ms/tick)"
        )
    for note in report.notes:
        click.echo(f"note: {note}")
    if report.recording is not None:
        result = report.recording
        click.echo(
            f"recording: {result.file} ({result.frames} frames, {result.facts} fact "
            f"lines, {result.beliefs} belief states)"
        )


@click.group("area")
def area() -> None:
    """Add, remove, list and show areas kept in the database."""


@area.command("add")
@click.argument("name")
@click.option(
    "--spec",
    "spec_text",
    help='JSON spec, e.g. \'{"shape": "circle", '
    '"center": [1, 2], "radius": 1.5, "area_type": "support"}\'.',
)
@click.option(
    "--file",
    "spec_file",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="A YAML/JSON file holding the spec.",
)
@click.pass_obj
def area_add(app: Any, name: str, spec_text: str | None, spec_file: Path | None) -> None:
    """Add or replace area NAME (see docs/producers.md for the spec)."""
    from toaster.documents import parse_text, read_document
    from toaster.world.scenario import check_area

    if (spec_text is None) == (spec_file is None):
        msg = "give the area as --spec JSON or --file PATH (exactly one)"
        raise InvalidInputError(msg)
    raw = (
        read_document(spec_file, "area spec")
        if spec_file is not None
        else parse_text(spec_text or "", "area spec --spec", json_only=True)
    )
    if not isinstance(raw, dict):
        msg = 'an area spec is a mapping such as {"shape": "polygon", "points": [...]}'
        raise InvalidInputError(msg)
    spec = check_area(name, raw, "area")
    app.db.store().put_area(name, spec, spec["owner"])
    click.echo(f"area {name} stored")


@area.command("clear")
@click.pass_obj
def area_clear(app: Any) -> None:
    """Remove every area (remove_all_areas)."""
    count = app.db.store().remove_all_areas()
    click.echo(f"{count} areas removed")


@area.command("remove")
@click.argument("name")
@click.pass_obj
def area_remove(app: Any, name: str) -> None:
    """Remove area NAME."""
    if not app.db.store().remove_area(name):
        msg = f"no area named {name!r}: see `toaster area list`"
        raise InvalidInputError(msg)
    click.echo(f"area {name} removed")


class AreaRow(NamedTuple):
    """One stored area, as ``area list`` shows it."""

    name: str
    shape: str
    area_type: str
    owner: str


@area.command("list")
@listing_options
@click.pass_obj
def area_list(app: Any, fmt: str | None, limit: int | None) -> None:
    """List stored areas (name, shape, type, owner)."""
    rows = [
        AreaRow(
            name,
            str(spec.get("shape", "")),
            str(spec.get("area_type", "")),
            str(spec.get("owner", "")),
        )
        for name, spec in sorted(app.db.store().areas().items())
    ]
    emit(rows, fmt, limit=limit, empty="(no area)")


@area.command("show")
@click.argument("name")
@click.pass_obj
def area_show(app: Any, name: str) -> None:
    """Show the spec of area NAME as JSON."""
    areas = app.db.store().areas()
    if name not in areas:
        msg = f"no area named {name!r}: see `toaster area list`"
        raise InvalidInputError(msg)
    click.echo(json.dumps(areas[name], indent=2, sort_keys=True))


@click.command("relpos")
@click.argument(
    "path", metavar="SCENARIO", type=click.Path(exists=True, dir_okay=False, path_type=Path)
)
@click.option("--at", "at", default="0s", metavar="T", help="Scenario time (2.5s; default 0s).")
@click.option("--viewer", required=True, help="The agent whose viewpoint is used.")
@click.option("--object", "object_id", required=True, help="The entity to locate.")
@click.option(
    "--reference",
    default=None,
    help="Locate it relative to this entity (default: relative to the viewer).",
)
def relpos(path: Path, at: str, viewer: str, object_id: str, reference: str | None) -> None:
    """Where an object is from an agent's viewpoint: left/right, in front/behind, above/below."""
    from toaster.producers import Runner, load_session
    from toaster.producers.spatial import relative_position_from
    from toaster.timeutil import check_ns

    offset = parse_duration_option(at, "--at")
    session = load_session(path)
    t_ns = check_ns(session.start_ns + offset, f"--at {at!r}: the scenario time")
    Runner(session.world, session.sources, []).tick(t_ns)
    words, (fwd, left, up) = relative_position_from(
        session.world, viewer, object_id, reference, config=session.config
    )
    where = ", ".join(words) or "same place"
    click.echo(
        f"{object_id}: {where} (relative to {reference or viewer}, from {viewer}'s "
        f"viewpoint; forward {fwd:+.2f} m, left {left:+.2f} m, up {up:+.2f} m)"
    )
