"""``toaster get-info`` and ``toaster set-info``: the original's services, as commands."""

from __future__ import annotations

from typing import Any

import click

from toaster.cli.checks import parse_time_option
from toaster.cli.output import emit, output_options, say

GET_TYPES = ("FACT", "EVENT", "ONTOLOGY", "ID", "ENTITY", "AGENT", "PROPERTY")
SET_TYPES = ("ENTITY", "FACT", "EVENT", "ONTOLOGY", "PROPERTY")


_MAX_LIMIT = 2**63 - 1


def fact_options(func: Any) -> Any:
    """Options naming a fact (subject, property, target and the rest of its key)."""
    for name, help_text in reversed((
        ("--agent", "Agent holding the belief (default: the self agent)."),
        ("--subject", "Subject id ('NULL' = any)."),
        ("--property", "Property, e.g. IsOn."),
        ("--target", "Target id ('NULL' = any, empty = none)."),
        ("--sub-property", "Sub-property, e.g. 3D."),
        ("--subject-owner", "Owner of the subject (joints)."),
        ("--target-owner", "Owner of the target."),
    )):
        func = click.option(name, help=help_text)(func)
    return func


def _self_agent(db: Any, agent: str | None) -> str:
    return agent or db.store().self_agent()


@click.command("get-info")
@click.argument("info_type", metavar="TYPE", type=click.Choice(GET_TYPES, case_sensitive=False))
@click.argument("sub_type", metavar="[SUBTYPE]", required=False, default="ALL")
@fact_options
@click.option("--id", "entity_id", help="Entity id (ID, PROPERTY).")
@click.option("--kind", help="Entity kind (ID) or event kind (EVENT).")
@click.option("--class", "entity_class", help="Ontology class (ONTOLOGY VALUE / LEAVE).")
@click.option("--key", help="Property key (PROPERTY).")
@click.option("--at", "at", metavar="TIME", help="As of TIME (ns, ISO date, 12.5s).")
@click.option("--from", "since", metavar="TIME", help="Window start (FACT, EVENT).")
@click.option("--to", "until", metavar="TIME", help="Window end (FACT, EVENT).")
@click.option("--limit", type=click.IntRange(0, _MAX_LIMIT), help="At most this many rows.")
@output_options
@click.pass_obj
def get_info(app: Any, info_type: str, sub_type: str, fmt: str | None, **opts: Any) -> None:
    """Read facts, events, ontology, entities, agents or properties.

    \b
    FACT [ALL|CURRENT|OLD|VALUE]  ALL = current + memory, OLD = memory;
                                  VALUE = one fact's value (now, or --at TIME)
    FACT CURRENT --at TIME        everything the agent believed at TIME
    EVENT                         events, --from/--to window, --kind appeared|changed|ended|event
    ONTOLOGY [ALL|VALUE|LEAVE]    VALUE: children of --class; LEAVE: instantiated descendants
    ID | ENTITY [ALL|VALUE]       entities (VALUE: --id)
    AGENT                         belief-holding agents and their view names
    PROPERTY [ALL|VALUE]          static properties (VALUE: --id, --key)
    """
    from toaster import queries as q

    db = app.db
    kind, sub = info_type.upper(), sub_type.upper()
    key = {"subject": opts["subject"], "property": opts["property"], "target": opts["target"],
           "sub_property": opts["sub_property"], "subject_owner": opts["subject_owner"],
           "target_owner": opts["target_owner"]}
    at, since, until = (parse_time_option(opts["at"], "--at"),
                        parse_time_option(opts["since"], "--from"),
                        parse_time_option(opts["until"], "--to"))
    if kind == "FACT":
        _check_sub(sub, ("ALL", "CURRENT", "OLD", "VALUE"), kind)
        agent = opts["agent"]
        if sub == "VALUE":
            agent = _self_agent(db, agent)
            db.store().check_agent(agent)
            if not (opts["subject"] and opts["property"]):
                raise click.UsageError("FACT VALUE needs --subject and --property")
            row = q.fact_value(db, agent, opts["subject"], opts["property"], opts["target"] or "",
                               at=at, sub_property=opts["sub_property"],
                               subject_owner=opts["subject_owner"],
                               target_owner=opts["target_owner"])
            emit([row] if row else [], fmt, empty="(the fact does not hold)")
            return
        if agent:
            db.store().check_agent(agent)
        if at is not None:
            if sub != "CURRENT":
                raise click.UsageError("--at works with FACT CURRENT (beliefs as of TIME)")
            rows = q.beliefs_at(db, _self_agent(db, agent), at, **key)
        elif sub == "CURRENT":
            rows = q.current_facts(db, agent, limit=opts["limit"], **key)
        elif sub == "OLD":
            rows = q.memory(db, agent, since=since, until=until, limit=opts["limit"], **key)
        else:
            rows = q.history(db, agent, since=since, until=until, limit=opts["limit"], **key)
        emit(rows, fmt)
    elif kind == "EVENT":
        if opts["agent"]:
            db.store().check_agent(opts["agent"])
        emit(q.events(db, opts["agent"], since=since, until=until, kind=opts["kind"],
                      limit=opts["limit"], **key), fmt)
    elif kind == "ONTOLOGY":
        _check_sub(sub, ("ALL", "VALUE", "LEAVE"), kind)
        if sub != "ALL" and not opts["entity_class"]:
            raise click.UsageError(f"ONTOLOGY {sub} needs --class")
        edges = (q.descendants(db, opts["entity_class"]) if sub == "LEAVE"
                 else q.ontology(db, opts["entity_class"] if sub == "VALUE" else None))
        emit(edges, fmt)
    elif kind in ("ID", "ENTITY"):
        _check_sub(sub, ("ALL", "VALUE"), kind)
        emit(q.entities(db, opts["entity_id"], kind=opts["kind"]), fmt)
    elif kind == "AGENT":
        emit(q.agents(db), fmt)
    else:
        _check_sub(sub, ("ALL", "VALUE"), kind)
        emit(q.properties(db, opts["entity_id"], opts["key"]), fmt)


def _check_sub(sub: str, allowed: tuple[str, ...], kind: str) -> None:
    if sub not in allowed:
        raise click.UsageError(f"unknown {kind} subtype {sub!r}: use one of {', '.join(allowed)}")


@click.command("set-info")
@click.argument("info_type", metavar="TYPE", required=False,
                type=click.Choice(SET_TYPES, case_sensitive=False))
@click.option("--file", "files", multiple=True, type=click.Path(dir_okay=False),
              help="A JSON/YAML batch or one of the original's XML seeds (repeatable; each "
                   "file is one transaction).")
@click.option("--add/--remove", default=True, help="Add (default) or remove.")
@fact_options
@click.option("--id", "entity_id", help="Entity id (ENTITY, PROPERTY).")
@click.option("--name", default="", help="Entity name (default: the id).")
@click.option("--type", "entity_kind", default="object",
              help="Entity kind: human, robot, object, joint, area...")
@click.option("--owner", default="", help="Owner of the entity (joints).")
@click.option("--self/--not-self", "is_self", default=None, help="Mark the agent as self.")
@click.option("--value", help="Symbolic value (FACT, default 'true') or property value.")
@click.option("--num", type=float, help="Numeric value.")
@click.option("--confidence", type=float, default=1.0, show_default=True)
@click.option("--observability", type=float, default=1.0, show_default=True)
@click.option("--property-type", default="", help="Property type, e.g. position.")
@click.option("--class", "entity_class", help="Ontology class.")
@click.option("--individual", help="Ontology individual.")
@click.option("--instantiated", is_flag=True, help="The ontology individual is an instance.")
@click.option("--key", help="Property key (PROPERTY).")
@click.option("--at", "at", metavar="TIME", help="When (default now).")
@click.option("--actor", help="FACT: the agent who made the change (it perceives it anywhere).")
@click.pass_obj
def set_info(app: Any, info_type: str | None, files: tuple[str, ...], add: bool,
             **opts: Any) -> None:
    """Write entities, facts, events, ontology rows or properties (one transaction).

    \b
    ENTITY   --id X --type human|robot|object|joint [--name] [--owner] [--self]; --remove
    FACT     --agent A --subject S --property P [--target T] [--value V] [--num N]
             [--confidence C] [--observability O] [--at TIME] [--actor AGENT]; --remove
             ends the current facts that match ('NULL' subject or target = any)
    EVENT    --agent A --subject S --property P [--target T] [--value V] [--at TIME]
    ONTOLOGY --class C --individual I [--instantiated]; --remove
    PROPERTY --id X --key K --value V; --remove (without --key: all of X)
    --file F batch files (JSON / YAML / the original's XML seeds)
    """
    from toaster.db.seed import fact_from_mapping, property_value

    db = app.db
    store = db.store()
    if files:
        for path in files:
            report = store.load_file(path)
            counts = ", ".join(f"{n} {kind}" for kind, n in report.items()) or "nothing"
            say(f"{path}: {counts}")
        if not info_type:
            return
    if not info_type:
        raise click.UsageError("give a TYPE (ENTITY, FACT, EVENT, ONTOLOGY, PROPERTY) or --file")
    kind = info_type.upper()
    at = parse_time_option(opts["at"], "--at")
    if kind == "ENTITY":
        entity_id = _need(opts, "entity_id", "--id")
        if add:
            store.add_entity(entity_id, opts["entity_kind"], opts["name"], opts["owner"],
                             is_self=opts["is_self"], t_ns=at)
            say(f"entity {entity_id!r} saved")
        else:
            store.remove_entity(entity_id)
            say(f"entity {entity_id!r} removed")
    elif kind in ("FACT", "EVENT"):
        agent = _self_agent(db, opts["agent"])
        _need(opts, "property", "--property")
        if kind == "FACT" and not add:
            n = store.retract_facts(agent, opts["property"], opts["subject"], opts["target"],
                                    sub_property=opts["sub_property"],
                                    subject_owner_id=opts["subject_owner"],
                                    target_owner_id=opts["target_owner"], t_ns=at,
                                    actor=opts["actor"])
            say(f"{n} fact(s) ended for {agent}")
            return
        _need(opts, "subject", "--subject")
        row = {k: opts[k] for k in ("subject", "property", "target", "sub_property",
                                    "subject_owner", "target_owner", "confidence",
                                    "observability", "property_type") if opts[k] is not None}
        row["value"] = opts["value"] if opts["value"] is not None else "true"
        if opts["num"] is not None:
            row["num"] = opts["num"]
        fact = fact_from_mapping(row)
        if kind == "EVENT":
            store.record_event(agent, fact, t_ns=at)
            say(f"event recorded for {agent}")
        else:
            outcome = store.assert_fact(agent, fact, t_ns=at, actor=opts["actor"])
            say(f"fact {outcome} for {agent}")
    elif kind == "ONTOLOGY":
        entity_class = _need(opts, "entity_class", "--class")
        if add:
            store.add_ontology(entity_class, _need(opts, "individual", "--individual"),
                               opts["instantiated"])
            say("ontology row saved")
        else:
            removed = store.remove_ontology(entity_class, opts["individual"])
            say(f"{removed} ontology row(s) removed")
    else:
        entity_id = _need(opts, "entity_id", "--id")
        if add:
            key = _need(opts, "key", "--key")
            store.set_property(entity_id, key, property_value(_need(opts, "value", "--value"),
                                                              key))
            say("property saved")
        else:
            say(f"{store.remove_property(entity_id, opts['key'])} property row(s) removed")


def _need(opts: dict[str, Any], name: str, flag: str) -> str:
    value = opts.get(name)
    if value in (None, ""):
        raise click.UsageError(f"missing {flag}")
    return str(value)
