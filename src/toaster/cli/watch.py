"""``toaster watch``: events pushed as they are committed (subscriptions)."""

from __future__ import annotations

import json
from typing import Any

import click


@click.command("watch")
@click.option("--agent", default=None, help="Agent pattern (glob: *, ?).")
@click.option("--subject", default=None, help="Subject pattern.")
@click.option("--property", "prop", default=None, help="Property pattern.")
@click.option("--target", default=None, help="Target pattern.")
@click.option("--json", "as_json", is_flag=True, help="JSON lines (times in ns).")
@click.option("--timeout", type=float, default=None,
              help="Stop after this many seconds without a matching event.")
@click.pass_obj
def watch(app: Any, agent: str | None, subject: str | None, prop: str | None,
          target: str | None, as_json: bool, timeout: float | None) -> None:
    """Print each appeared / changed / ended event matching the patterns as it is committed
    (by `toaster serve`, `toaster run` or any writer). Ctrl-C stops."""
    from toaster.queries import watch as watch_events
    from toaster.timeutil import format_ns

    try:
        for row in watch_events(app.db, agent=agent, subject=subject, property=prop,
                                target=target, timeout_s=timeout):
            if as_json:
                click.echo(json.dumps(row._asdict()))
            else:
                value = row.value_text if row.value_text not in (None, "") else row.value_num
                click.echo(f"{format_ns(row.stamp_ns)}  {row.agent_id:<12} {row.kind:<8} "
                           f"{row.subject_id} {row.property} {row.target_id or '-'}"
                           f"{'' if value in (None, '') else f' = {value}'}")
    except KeyboardInterrupt:
        pass
