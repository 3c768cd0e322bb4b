"""``toaster watch``: events pushed as they are committed (subscriptions)."""

from __future__ import annotations

import itertools
from typing import Any

import click

from toaster.cli.output import RowWriter, listing_options


@click.command("watch")
@click.option("--agent", default=None, help="Agent pattern (glob: *, ?).")
@click.option("--subject", default=None, help="Subject pattern.")
@click.option("--property", "prop", default=None, help="Property pattern.")
@click.option("--target", default=None, help="Target pattern.")
@click.option(
    "--timeout",
    type=float,
    default=None,
    help="Stop after this many seconds without a matching event.",
)
@listing_options
@click.pass_obj
def watch(
    app: Any,
    agent: str | None,
    subject: str | None,
    prop: str | None,
    target: str | None,
    timeout: float | None,
    fmt: str | None,
    limit: int | None,
) -> None:
    """Print each appeared / changed / ended event matching the patterns as it is committed
    (by `toaster serve`, `toaster run` or any writer); --limit N stops after N. Ctrl-C stops."""
    from toaster.cli.checks import command_frame
    from toaster.model import EventRow
    from toaster.queries import watch as watch_events
    from toaster.timeutil import TimeFrame

    def frame_now() -> TimeFrame:
        return command_frame() or TimeFrame(None)

    frame = frame_now()  # (read again while the data has no start yet)

    def line(row: EventRow) -> str:
        value = row.value_text if row.value_text not in (None, "") else row.value_num
        return (
            f"{frame.show(row.stamp_ns)}  {row.agent_id:<12} {row.kind:<8} "
            f"{row.subject_id} {row.property} {row.target_id or '-'}"
            f"{'' if value in (None, '') else f' = {value}'}"
        )

    out = RowWriter(fmt, EventRow._fields, line)
    if limit == 0:
        return
    events = watch_events(
        app.db, agent=agent, subject=subject, property=prop, target=target, timeout_s=timeout
    )
    try:
        for row in itertools.islice(events, limit):
            frame = frame if frame.start_ns is not None else frame_now()
            out.write(row, frame)
    except KeyboardInterrupt:
        pass
