"""``toaster export`` (facts, memory, history, events to CSV / JSON lines / Parquet) and
``toaster record`` (frames and events to a rosbag2 MCAP bag)."""

from __future__ import annotations

from typing import Any

import click

from toaster.cli.plot import _many, parse_window, window_options


@click.command("export")
@click.argument("kind", type=click.Choice(["facts", "memory", "history", "events"]))
@click.argument("output", type=click.Path(dir_okay=False, writable=True))
@click.option("--agent", "-a", multiple=True, help="Agent (repeatable; default: every agent).")
@click.option("--subject", "-s", multiple=True, help="Subject id (repeatable).")
@click.option("--property", "-p", "prop", multiple=True, help="Property (repeatable).")
@click.option("--target", "-t", multiple=True, help="Target id (repeatable).")
@window_options
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["csv", "jsonl", "parquet"]),
    help="Output format (default: from OUTPUT's suffix).",
)
@click.pass_obj
def export(
    app: Any,
    kind: str,
    output: str,
    agent: tuple[str, ...],
    subject: tuple[str, ...],
    prop: tuple[str, ...],
    target: tuple[str, ...],
    since: str | None,
    until: str | None,
    fmt: str | None,
) -> None:
    """Write KIND (facts = current, memory, history, events) to OUTPUT (.csv, .jsonl, .parquet).

    One row per interval or event, every field, times in integer ns. Parquet keeps the types
    (each X_ns time also as a UTC timestamp column X; missing values null) and needs pyarrow
    (pip install 'toaster[export]'); toaster.outputs.export.read_frame reads any of them into
    pandas.
    """
    from toaster.outputs.export import export as write

    db = app.db
    lo, hi = parse_window(since, until)
    result = write(
        db,
        kind,
        output,
        format=fmt,
        agent=_many(agent),
        subject=_many(subject),
        property=_many(prop),
        target=_many(target),
        since=lo,
        until=hi,
    )
    click.echo(f"wrote {result.rows} {kind} rows to {result.path} ({result.format})")


@click.command("record")
@click.argument("frames", type=click.Path(exists=True, dir_okay=False))
@click.argument("output", type=click.Path())
@click.option(
    "--agent",
    "-a",
    multiple=True,
    help="Agent (or nested holder A>B) whose events and beliefs to record "
    "(repeatable; default: all).",
)
@window_options
@click.option("--frame-id", default="map", show_default=True, help="Fixed frame of the markers.")
@click.option(
    "--distro",
    help="ROS distro: message definitions and container: humble (rosbag2 "
    "metadata version 5), iron (8), jazzy, kilted (9), noetic (a ROS 1 .bag). "
    "Default: noetic if OUTPUT ends in .bag, else humble.",
)
@click.option(
    "--toaster-names",
    type=click.Choice(["ros2", "ros1"]),
    help="toaster_msgs field names: ros2 (snake_case, decoded by Foxglove and ROS 2 "
    "tools; the default of ROS 2 bags) or ros1 (the original's camelCase; the only "
    "one of ROS 1 bags); toaster run reads both.",
)
@click.option(
    "--no-facts", is_flag=True, help="Leave the database out (events, fact lists and beliefs)."
)
@click.pass_obj
def record(
    app: Any,
    frames: str,
    output: str,
    agent: tuple[str, ...],
    since: str | None,
    until: str | None,
    frame_id: str,
    distro: str | None,
    toaster_names: str | None,
    no_facts: bool,
) -> None:
    """Record FRAMES (JSON lines of poses) and the database's facts into the bag OUTPUT.

    Each line of FRAMES: {"t_ns": ..., "entities": [[id, kind, x, y, z, yaw], ...],
    "areas": [[id, [[x, y], ...]], ...]}. OUTPUT is a new rosbag2 folder holding an .mcap
    file (Foxglove, Lichtblick, ros2 bag play), or a ROS 1 file NAME.bag (rosbag play).
    Needs rosbags (pip install 'toaster[rosbag]'); see docs/recordings.md.
    """
    from toaster.errors import FileFormatError
    from toaster.outputs.recording import read_frames
    from toaster.outputs.recording import record as write

    try:  # read_frames lets undecodable bytes and deep nesting through (issue 14)
        poses = read_frames(frames)
    except (UnicodeDecodeError, RecursionError) as exc:
        reason = "not UTF-8 text" if isinstance(exc, UnicodeDecodeError) else "nested too deep"
        msg = f"cannot read frames {frames!r}: {reason}; write one JSON frame per line"
        raise FileFormatError(msg) from None
    db = app.db
    lo, hi = parse_window(since, until)
    result = write(
        output,
        poses,
        db=None if no_facts else db,
        agent=_many(agent),
        since=lo,
        until=hi,
        frame_id=frame_id,
        distro=distro,
        toaster_names=toaster_names,
    )
    click.echo(
        f"wrote {result.frames} frames, {result.facts} fact lines and "
        f"{result.beliefs} belief states to {result.file}"
    )
