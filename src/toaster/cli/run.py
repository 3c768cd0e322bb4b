"""``toaster run`` (tick sources and producers into the store) and ``toaster area`` (areas)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import click

from toaster.cli.checks import parse_duration_option
from toaster.cli.rosopts import pose_topics as parse_pose_topics
from toaster.cli.rosopts import ros_input_options
from toaster.errors import InvalidInputError


def _database(ctx: click.Context, url: str | None) -> Any:
    if url:
        from toaster.session import connect

        db = connect(url)
        ctx.call_on_close(db.close)
        return db
    app = ctx.find_object(object)
    return app.db if app is not None and hasattr(app, "db") else None


@click.command("run")
@click.argument("path", metavar="SCENARIO_OR_RECORDING",
                type=click.Path(exists=True, path_type=Path))
@click.option("--db", "url", metavar="URL", help="Database URL (default: the group's --db).")
@click.option("--rate", type=float, help="Ticks per second (default: the file's, 30 / 2.5 Hz).")
@click.option("--until", "until", metavar="T", help="Stop after this much input time (20s).")
@click.option("--realtime", is_flag=True, help="Pace ticks to the wall clock.")
@click.option("--fps", type=float, metavar="FPS", help="Frame rate of an obsmat file's frame "
              "numbers (default 25, as ETH/UCY); checked against its annotated velocities.")
@click.option("--holders", metavar="none|humans|ID[,ID...]", help="Humans that hold beliefs "
              "(store agents). Default: a scenario's config belief_holders, else humans; none "
              "for recordings.")
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False,
                                                         path_type=Path),
              metavar="FILE", help="Producer thresholds (YAML/JSON mapping, e.g. "
              "toward_range_humans: 3.6) laid over the file's own config.")
@ros_input_options
@click.option("--no-db", is_flag=True, help="Compute only; write nothing.")
@click.option("--record", "record_dir", type=click.Path(path_type=Path), metavar="DIR",
              help="Also write the run as a rosbag2/MCAP recording in the new folder DIR (/tf, "
                   "pdg's entity lists, markers, the producers' fact lists, the facts' events; "
                   "docs/recordings.md) for Foxglove, Lichtblick, RViz 2 or `toaster run DIR`; "
                   "needs toaster[rosbag].")
@click.pass_context
def run(ctx: click.Context, path: Path, url: str | None, rate: float | None, until: str | None,
        realtime: bool, fps: float | None, holders: str | None, config_file: Path | None,
        tf_map: Path | None, pose_topics: tuple[str, ...], no_db: bool,
        record_dir: Path | None) -> None:
    """Tick a scenario (.yaml/.json), recording (obsmat .txt, .csv, .jsonl) or ROS bag
    (.bag, .mcap, .db3 or a rosbag2 folder) into the store.

    Areas stored in the database are added to the file's; the file's areas are stored.
    Same input into a fresh database gives the same facts and events.
    """
    from toaster.producers import Runner, load_session
    from toaster.producers.config import read_config_file
    from toaster.timeutil import check_rate

    if record_dir is not None and record_dir.exists():
        msg = f"cannot record into {str(record_dir)!r}: it exists; give a new folder name"
        raise InvalidInputError(msg)
    if rate is not None:
        rate = check_rate(rate, "--rate")
    until_ns = None if until is None else parse_duration_option(until, "--until")
    overrides = read_config_file(config_file) if config_file is not None else None
    store = None if no_db else _database(ctx, url).store()
    session = load_session(path, store.areas() if store is not None else None, fps=fps,
                           holders=holders, config=overrides, tf_map=tf_map,
                           pose_topics=parse_pose_topics(pose_topics))
    end = session.end_ns
    if until_ns is not None:
        end = min(end, session.start_ns + until_ns)
    runner = Runner(session.world, session.sources, session.producers, store=store,
                    agent_id=session.self_id, config=session.config)
    if store is not None:
        session.register(store)
    hz = rate or session.rate_hz
    total = max(1, int((end - session.start_ns) * hz / 1e9) + 1)
    frames: list[tuple[Any, ...]] = []

    def grab(t_ns: int) -> None:
        if record_dir is not None:
            frames.append(session.frame(t_ns, with_areas=not frames))

    wall = time.perf_counter()
    if sys.stderr.isatty():
        from rich.progress import Progress

        with Progress(transient=True) as bar:
            task = bar.add_task(f"{path.name}", total=total)

            def advance(t_ns: int) -> None:
                grab(t_ns)
                bar.advance(task)

            runner.run(session.start_ns, end, hz, realtime=realtime, on_tick=advance)
    else:
        runner.run(session.start_ns, end, hz, realtime=realtime, on_tick=grab)
    elapsed = time.perf_counter() - wall
    stats = runner.stats
    input_s = (end - session.start_ns) / 1e9
    click.echo(f"{path.name}: {stats.ticks} ticks over {input_s:.1f} s of input in "
               f"{elapsed:.2f} s ({input_s / elapsed if elapsed else 0:.0f}× real time)")
    click.echo(f"facts: {stats.facts} emitted; events: {stats.events} (appeared "
               f"{stats.appeared}, changed {stats.changed}, ended {stats.ended})")
    for name, seconds in sorted(stats.seconds.items(), key=lambda kv: -kv[1]):
        click.echo(f"  {name:<14} {seconds * 1e3:9.1f} ms  "
                   f"({seconds / max(stats.ticks, 1) * 1e3:.3f} ms/tick)")
    if record_dir is not None:
        from toaster.recording import record

        result = record(record_dir, frames, db=store.db if store is not None else None)
        click.echo(f"recording: {result.mcap} ({result.frames} frames, {result.facts} fact lines)")


@click.group("area")
def area() -> None:
    """Add, remove, list and show areas kept in the database."""


@area.command("add")
@click.argument("name")
@click.option("--spec", "spec_text", help='JSON spec, e.g. \'{"shape": "circle", '
              '"center": [1, 2], "radius": 1.5, "area_type": "support"}\'.')
@click.option("--file", "spec_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="A YAML/JSON file holding the spec.")
@click.pass_context
def area_add(ctx: click.Context, name: str, spec_text: str | None, spec_file: Path | None
             ) -> None:
    """Add or replace area NAME (see docs/producers.md for the spec)."""
    from toaster.documents import parse_text, read_document
    from toaster.world.scenario import check_area

    if (spec_text is None) == (spec_file is None):
        msg = "give the area as --spec JSON or --file PATH (exactly one)"
        raise InvalidInputError(msg)
    raw = (read_document(spec_file, "area spec") if spec_file is not None
           else parse_text(spec_text or "", "area spec --spec", json_only=True))
    if not isinstance(raw, dict):
        msg = "an area spec is a mapping such as {\"shape\": \"polygon\", \"points\": [...]}"
        raise InvalidInputError(msg)
    spec = check_area(name, raw, "area")
    _database(ctx, None).store().put_area(name, spec, spec["owner"])
    click.echo(f"area {name} stored")


@area.command("clear")
@click.pass_context
def area_clear(ctx: click.Context) -> None:
    """Remove every area (remove_all_areas)."""
    count = _database(ctx, None).store().remove_all_areas()
    click.echo(f"{count} areas removed")


@area.command("remove")
@click.argument("name")
@click.pass_context
def area_remove(ctx: click.Context, name: str) -> None:
    """Remove area NAME."""
    if not _database(ctx, None).store().remove_area(name):
        msg = f"no area named {name!r}: see `toaster area list`"
        raise InvalidInputError(msg)
    click.echo(f"area {name} removed")


@area.command("list")
@click.pass_context
def area_list(ctx: click.Context) -> None:
    """List stored areas."""
    for name, spec in sorted(_database(ctx, None).store().areas().items()):
        owner = f" owner={spec.get('owner')}" if spec.get("owner") else ""
        click.echo(f"{name}\t{spec.get('shape')}\t{spec.get('area_type', '')}{owner}")


@area.command("show")
@click.argument("name")
@click.pass_context
def area_show(ctx: click.Context, name: str) -> None:
    """Show the spec of area NAME as JSON."""
    areas = _database(ctx, None).store().areas()
    if name not in areas:
        msg = f"no area named {name!r}: see `toaster area list`"
        raise InvalidInputError(msg)
    click.echo(json.dumps(areas[name], indent=2, sort_keys=True))


@click.command("relpos")
@click.argument("path", metavar="SCENARIO",
                type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--at", "at", default="0s", metavar="T", help="Scenario time (2.5s; default 0s).")
@click.option("--viewer", required=True, help="The agent whose viewpoint is used.")
@click.option("--object", "object_id", required=True, help="The entity to locate.")
@click.option("--reference", default=None, help="Locate it relative to this entity "
              "(default: relative to the viewer).")
def relpos(path: Path, at: str, viewer: str, object_id: str, reference: str | None) -> None:
    """Where an object is from an agent's viewpoint: left/right, in front/behind, above/below."""
    from toaster.producers import Runner, load_session
    from toaster.producers.spatial import relative_position_from
    from toaster.timeutil import check_ns

    offset = parse_duration_option(at, "--at")
    session = load_session(path)
    t_ns = check_ns(session.start_ns + offset, f"--at {at!r}: the scenario time")
    Runner(session.world, session.sources, []).tick(t_ns)
    words, (fwd, left, up) = relative_position_from(session.world, viewer, object_id, reference,
                                                    config=session.config)
    where = ", ".join(words) or "same place"
    click.echo(f"{object_id}: {where} (relative to {reference or viewer}, from {viewer}'s "
               f"viewpoint; forward {fwd:+.2f} m, left {left:+.2f} m, up {up:+.2f} m)")
