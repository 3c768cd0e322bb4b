"""``toaster export`` (facts, memory, history, events to CSV / JSON lines / Parquet) and
``toaster record`` (frames and events to a rosbag2 MCAP bag)."""

from __future__ import annotations

import click

from toaster.cli.plot import _many, db_option, open_db, parse_window, window_options


@click.command("export")
@click.argument("kind", type=click.Choice(["facts", "memory", "history", "events"]))
@click.argument("output", type=click.Path(dir_okay=False, writable=True))
@click.option("--agent", "-a", multiple=True, help="Agent (repeatable; default: every agent).")
@click.option("--subject", "-s", multiple=True, help="Subject id (repeatable).")
@click.option("--property", "-p", "prop", multiple=True, help="Property (repeatable).")
@click.option("--target", "-t", multiple=True, help="Target id (repeatable).")
@window_options
@click.option("--format", "fmt", type=click.Choice(["csv", "jsonl", "parquet"]),
              help="Output format (default: from OUTPUT's suffix).")
@db_option
def export(kind: str, output: str, agent: tuple[str, ...], subject: tuple[str, ...],
           prop: tuple[str, ...], target: tuple[str, ...], since: str | None,
           until: str | None, fmt: str | None, url: str | None) -> None:
    """Write KIND (facts = current, memory, history, events) to OUTPUT (.csv, .jsonl, .parquet).

    One row per interval or event, every field, times in integer ns. Parquet needs pyarrow
    (pip install 'toaster[export]').
    """
    from toaster.export import export as write

    with open_db(url) as db:
        lo, hi = parse_window(since, until)
        result = write(db, kind, output, format=fmt, agent=_many(agent),
                       subject=_many(subject), property=_many(prop), target=_many(target),
                       since=lo, until=hi)
    click.echo(f"wrote {result.rows} {kind} rows to {result.path} ({result.format})")


@click.command("record")
@click.argument("frames", type=click.Path(exists=True, dir_okay=False))
@click.argument("output", type=click.Path(file_okay=False))
@click.option("--agent", "-a", multiple=True, help="Agent whose events to record (repeatable).")
@window_options
@click.option("--frame-id", default="map", show_default=True, help="Fixed frame of the markers.")
@click.option("--distro", default="humble", show_default=True,
              help="ROS 2 distro: message definitions and rosbag2 metadata version (humble 5, "
                   "iron 8, jazzy/kilted 9).")
@click.option("--toaster-names", type=click.Choice(["ros2", "ros1"]), default="ros2",
              show_default=True, help="toaster_msgs field names: ros2 (snake_case, decoded by "
              "Foxglove and ROS 2 tools) or ros1 (the original's camelCase); toaster run "
              "reads both.")
@click.option("--no-facts", is_flag=True, help="Leave the database's events out.")
@db_option
def record(frames: str, output: str, agent: tuple[str, ...], since: str | None,
           until: str | None, frame_id: str, distro: str, toaster_names: str, no_facts: bool,
           url: str | None) -> None:
    """Record FRAMES (JSON lines of poses) and the database's events into the bag OUTPUT.

    Each line of FRAMES: {"t_ns": ..., "entities": [[id, kind, x, y, z, yaw], ...],
    "areas": [[id, [[x, y], ...]], ...]}. OUTPUT is a new rosbag2 directory holding an .mcap
    file (Foxglove, Lichtblick, ros2 bag play). Needs rosbags (pip install 'toaster[rosbag]').
    """
    from toaster.errors import FileFormatError
    from toaster.recording import read_frames
    from toaster.recording import record as write

    try:  # read_frames lets undecodable bytes and deep nesting through (issue 14)
        poses = read_frames(frames)
    except (UnicodeDecodeError, RecursionError) as exc:
        reason = "not UTF-8 text" if isinstance(exc, UnicodeDecodeError) else "nested too deep"
        msg = f"cannot read frames {frames!r}: {reason}; write one JSON frame per line"
        raise FileFormatError(msg) from None
    with open_db(url) as db:
        lo, hi = parse_window(since, until)
        result = write(output, poses, db=None if no_facts else db,
                       agent=_many(agent), since=lo, until=hi, frame_id=frame_id,
                       distro=distro, toaster_names=toaster_names)
    click.echo(f"wrote {result.frames} frames and {result.facts} fact lines to {result.mcap}")
