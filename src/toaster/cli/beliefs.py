"""``toaster beliefs``: each agent's beliefs, false-belief reports, scenarios, rule settings."""

from __future__ import annotations

import json
from typing import Any

import click

from toaster.cli.checks import parse_json_option, parse_time_option
from toaster.cli.output import emit, listing_options, mode, say


def _at(value: str | None) -> int | None:
    return parse_time_option(value, "--at")


def _about(value: str | None) -> list[str] | None:
    return None if not value else [part for part in value.split(",") if part]


@click.group()
def beliefs() -> None:
    """Per-agent belief states kept by the perspective-taking rules.

    A's model of B's beliefs is the holder ``A>B`` (``--about B``; ``--about B,C`` for deeper).
    """


@beliefs.command("show")
@click.argument("agent")
@click.option("--about", help="Show AGENT's model of this agent's beliefs (A>B).")
@click.option("--at", "at", metavar="TIME", help="As of TIME (default now).")
@click.option("--subject")
@click.option("--property")
@click.option("--target")
@listing_options
@click.pass_obj
def show(
    app: Any,
    agent: str,
    about: str | None,
    at: str | None,
    subject: str | None,
    property: str | None,
    target: str | None,
    fmt: str | None,
    limit: int | None,
) -> None:
    """What AGENT believes (now or --at TIME)."""
    from toaster.beliefs import api

    rows = api.beliefs(
        app.db, agent, _about(about), at=_at(at), subject=subject, property=property, target=target
    )
    emit(rows, fmt, limit=limit, empty=f"({agent} believes nothing that matches)")


@beliefs.command("value")
@click.argument("agent")
@click.option("--subject", required=True)
@click.option("--property", required=True)
@click.option("--target", default="")
@click.option("--about", help="AGENT's model of this agent's beliefs.")
@click.option("--at", "at", metavar="TIME")
@listing_options
@click.pass_obj
def value(
    app: Any,
    agent: str,
    subject: str,
    property: str,
    target: str,
    about: str | None,
    at: str | None,
    fmt: str | None,
    limit: int | None,
) -> None:
    """One belief of AGENT: its value and interval, or that it is not held."""
    from toaster.beliefs import api

    row = api.belief_value(
        app.db, agent, subject, property, target, about=_about(about), at=_at(at)
    )
    emit([row] if row else [], fmt, limit=limit, empty="(not believed)")


@beliefs.command("diff")
@click.argument("agent")
@click.option("--other", help="Compare with this agent (default: the self agent).")
@click.option("--about", help="Use AGENT's model of this agent.")
@click.option("--at", "at", metavar="TIME")
@listing_options
@click.pass_obj
def diff(
    app: Any,
    agent: str,
    other: str | None,
    about: str | None,
    at: str | None,
    fmt: str | None,
    limit: int | None,
) -> None:
    """False-belief report: where AGENT and OTHER disagree, each one's value and confidence
    under its name (--json / --csv: value_a is AGENT's, value_b OTHER's, named in agent_a and
    agent_b)."""
    from toaster.beliefs import api

    rows = api.false_beliefs(app.db, agent, other, about=about, at=_at(at))
    a = f"{agent}>{about}" if about else agent
    b = other or api.self_agent(app.db)
    key = ["subject_id", "property", "target_id", "sub_property"]
    records: list[tuple[Any, ...]]
    if mode(fmt) in ("json", "csv"):
        columns = ["agent_a", "agent_b", *api.BeliefDiff._fields]
        records = [(a, b, *row) for row in rows]
    else:
        columns = [*key, f"value ({a})", f"confidence ({a})", f"value ({b})", f"confidence ({b})"]
        records = [tuple(row) for row in rows]
    emit(records, fmt, columns=columns, limit=limit, empty="(no disagreement)")


@beliefs.command("history")
@click.option("--subject", required=True)
@click.option("--property", required=True)
@click.option("--target")
@click.option("--agent", "agents", multiple=True, help="Only these holders (repeatable).")
@listing_options
@click.pass_obj
def history(
    app: Any,
    subject: str,
    property: str,
    target: str | None,
    agents: tuple[str, ...],
    fmt: str | None,
    limit: int | None,
) -> None:
    """Every interval of one belief across the robot, the agents and nested holders."""
    from toaster.beliefs import api

    rows = api.belief_history(app.db, subject, property, target, agents=list(agents) or None)
    emit(rows, fmt, limit=limit)


@beliefs.command("holders")
@listing_options
@click.pass_obj
def holders(app: Any, fmt: str | None, limit: int | None) -> None:
    """Belief holders other than the self agent (first order, then nested A>B)."""
    from toaster.beliefs import api

    emit(
        [(holder,) for holder in api.holders(app.db)],
        fmt,
        columns=["holder"],
        limit=limit,
        empty="(no belief holder but the robot)",
    )


@beliefs.command("config")
@click.argument("key", required=False)
@click.argument("value", required=False)
@click.option(
    "--reset", is_flag=True, help="Put KEY (or, without KEY, every setting) back to its default."
)
@click.pass_obj
def config(app: Any, key: str | None, value: str | None, reset: bool) -> None:
    """Show the rule settings, or set KEY to VALUE (JSON: depth 1, enabled false...)."""
    from toaster.beliefs import api
    from toaster.rules import settings as cfg

    if reset:
        if value is not None:
            raise click.UsageError("--reset takes KEY alone (no VALUE)")
        settings = api.reset(app.db, *([key] if key else []))
        say(
            f"beliefs.{key} = {json.dumps(settings[key])} (default)"
            if key
            else "every beliefs setting is back to its default"
        )
        return
    if key is None:
        click.echo(json.dumps(api.config(app.db), indent=2, sort_keys=True))
        return
    if value is None:
        click.echo(json.dumps(api.config(app.db)[cfg.check_key(key)]))
        return
    parsed = parse_json_option(value, f"beliefs setting {key}")
    api.configure(app.db, **{key: parsed})
    say(f"beliefs.{key} = {json.dumps(parsed)}")


@beliefs.command("replay")
@click.argument("scenario", type=click.Path(exists=True, dir_okay=False))
@click.option("--check", is_flag=True, help="Exit 1 unless every expectation holds.")
@click.pass_obj
def replay(app: Any, scenario: str, check: bool) -> None:
    """Replay a belief scenario (timed facts and room changes) into the database."""
    from toaster.beliefs import scenario as sc

    loaded, failures = sc.replay_and_check(app.db, scenario)
    say(f"replayed {loaded.name}: {len(loaded.steps)} steps")
    for failure in failures:
        click.echo(failure)
    if loaded.expect:
        say(f"{len(loaded.expect) - len(failures)}/{len(loaded.expect)} expectations hold")
    if check and failures:
        raise SystemExit(1)


@click.command("tell")
@click.argument("speaker")
@click.argument("subject")
@click.argument("property")
@click.argument("target", required=False, default="")
@click.option(
    "--to",
    "listeners",
    multiple=True,
    metavar="AGENT",
    help="A listener (repeatable); none: everyone in SPEAKER's room hears it.",
)
@click.option("--value", default="true", show_default=True)
@click.option("--at", "at", metavar="TIME", help="When (default now).")
@click.pass_obj
def tell_cmd(
    app: Any,
    speaker: str,
    subject: str,
    property: str,
    target: str,
    listeners: tuple[str, ...],
    value: str,
    at: str | None,
) -> None:
    """SPEAKER tells SUBJECT PROPERTY [TARGET]: listeners who trust SPEAKER believe it, and
    everyone who hears it knows they were told (toaster.beliefs.tell)."""
    from toaster.beliefs.tell import tell
    from toaster.model import Fact

    learnt = tell(
        app.db,
        speaker,
        Fact(subject, property, target, value),
        listeners=list(listeners) or None,
        t_ns=_at(at),
    )
    say(f"told: {', '.join(learnt) or 'nobody (no listener, or none trusts ' + speaker + ')'}")
