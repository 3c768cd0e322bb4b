"""``toaster demo``: replay a shipped scenario into SQLite and answer questions from memory."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import click

from toaster.cli.output import emit, say

DEMO_FILE = "toaster-demo.db"


@click.command()
@click.option("--keep", is_flag=True, help="Keep an existing demo database instead of "
              "recreating it.")
@click.pass_obj
def demo(app: Any, keep: bool) -> None:
    """Replay the mug scenario and ask the database what happened.

    Without --db the demo writes a fresh ./toaster-demo.db (never your toaster.db); with --db
    the target must be empty.
    """
    from toaster import queries as q
    from toaster.session import connect
    from toaster.timeutil import NS_PER_S, format_ns, parse_time

    if app.url is None:
        path = Path(DEMO_FILE)
        if path.exists() and not keep:
            for suffix in ("", "-wal", "-shm"):
                Path(DEMO_FILE + suffix).unlink(missing_ok=True)
        app._db = connect(f"sqlite:///{DEMO_FILE}")
    db = app.db
    if q.history(db, limit=1):
        raise click.ClickException(f"{db.url} already holds facts: give an empty --db")
    scenario = resources.files("toaster") / "examples" / "demo_mug.yaml"
    with resources.as_file(scenario) as file:
        report = db.store().load_file(file)
    say(f"replayed {scenario.name} into {db.url}: "
        + ", ".join(f"{n} {kind}" for kind, n in report.items()))
    start = parse_time("2026-11-22T12:00:00Z")
    now = start + 420 * NS_PER_S

    click.echo("\nWhat the robot believes now:")
    emit(q.current_facts(db, "PR2_ROBOT"), None)
    click.echo("\nWhere is the mug that was on the table?  (memory)")
    for row in q.memory(db, "PR2_ROBOT", subject="MUG", property="IsOn"):
        click.echo(f"  {row.subject_id} was {row.property} {row.target_id} from "
                   f"{format_ns(row.valid_from_ns)} to {format_ns(row.valid_to_ns)}")
    held = q.fact_value(db, "PR2_ROBOT", "MUG", "IsInHand", "BOB")
    if held:
        click.echo(f"  now it {held.property} {held.target_id} (since "
                   f"{format_ns(held.valid_from_ns)})")
    click.echo(f"\nWho picked it up, and when?  (events; 'now' = {format_ns(now)})")
    for event in q.events(db, "PR2_ROBOT", subject="MUG", property="IsInHand", kind="appeared"):
        minutes = (now - event.stamp_ns) / (60 * NS_PER_S)
        click.echo(f"  {event.target_id} picked it up {minutes:.0f} minutes ago "
                   f"({format_ns(event.stamp_ns)})")
    at = start + 100 * NS_PER_S
    click.echo(f"\nEverything the robot believed at {format_ns(at)}:  (as-of)")
    emit(q.beliefs_at(db, "PR2_ROBOT", at), None)
    click.echo("\nInstantiated containers (ontology LEAVE):")
    emit(q.descendants(db, "container"), None)
    click.echo(f"\nTry: toaster --db sqlite:///{DEMO_FILE} get-info EVENT")
