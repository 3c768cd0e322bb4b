"""``toaster tolerance``: how much a number may move before it is written (settings as data)."""

from __future__ import annotations

import json
from typing import Any

import click

from toaster.cli.checks import parse_json_option
from toaster.cli.output import emit, listing_options


@click.command("tolerance")
@click.argument("property", required=False)
@click.argument("value", required=False)
@listing_options
@click.pass_obj
def tolerance(
    app: Any, property: str | None, value: str | None, fmt: str | None, limit: int | None
) -> None:
    """List the tolerances of continuous values (of PROPERTY), or set PROPERTY's to VALUE.

    VALUE is JSON: a number (the value's tolerance, in the property's unit) or
    '{"value": 0.05, "confidence": 0.05, "observability": 0}'. PROPERTY '*' is every property
    without its own. Running stores of the database take the change at their next tick.
    """
    from toaster.db import tolerance as tol

    store = app.db.store()
    if value is None:
        table = store.tolerances()
        rows = [(p, *t) for p, t in sorted(table.items()) if property is None or p == property]
        if property is not None and not rows:
            rows = [(property, *table["*"])]  # no own: the rest's
        emit(rows, fmt, columns=["property", *tol.Tolerance._fields], limit=limit)
        return
    parsed = parse_json_option(
        value,
        "VALUE",
        usage=(
            f'VALUE {value!r} is not JSON: give 0.05 or \'{{"value": 0.05, "confidence": 0.05}}\''
        ),
    )
    store.put_setting(tol.SCOPE, property, parsed)
    click.echo(f"tolerance {property} = {json.dumps(store.tolerances()[property]._asdict())}")
