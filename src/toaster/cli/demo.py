"""``toaster demo``: the whole job on the spatial Sally-Anne scenario (:mod:`toaster.app.demo`)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

DEMO_FILE = "toaster-demo.db"
DEMO_PICTURE = "toaster-demo.png"


@click.command()
@click.option(
    "--picture",
    type=click.Path(dir_okay=False, path_type=Path),
    default=DEMO_PICTURE,
    show_default=True,
    metavar="FILE",
    help="Where to draw the marble's timeline (.png, .svg, .pdf; .dat or .csv for data).",
)
@click.pass_obj
def demo(app: Any, picture: Path) -> None:
    """Geometry -> facts -> Sally's false belief -> SQL -> a timeline picture.

    Runs the shipped spatial Sally-Anne scenario into a fresh ./toaster-demo.db (never your
    toaster.db; recreated on every run) or into --db, which must hold no facts, and tells
    what happened.
    """
    from toaster.app.demo import check_picture, run_demo
    from toaster.app.session import connect

    check_picture(picture)
    if app.url is None:
        for suffix in ("", "-wal", "-shm", "-journal"):
            Path(DEMO_FILE + suffix).unlink(missing_ok=True)
        app._db = connect(f"sqlite:///{DEMO_FILE}")
    if sys.stderr.isatty():
        from rich.progress import Progress

        with Progress(transient=True) as bar:
            task = bar.add_task("Sally-Anne", total=None)
            result = run_demo(
                app.db,
                picture,
                time_style=app.time_style,
                on_tick=lambda done, total: bar.update(task, completed=done, total=total),
            )
    else:
        result = run_demo(app.db, picture, time_style=app.time_style)
    click.echo(result.story())
