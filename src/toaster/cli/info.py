"""``toaster get-info`` and ``toaster set-info``: the original's services, as commands."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import click

from toaster.cli.checks import parse_time_option
from toaster.cli.output import emit, listing_options, say

if TYPE_CHECKING:
    from toaster.db.database import Database
    from toaster.db.writer.store import Store

GET_TYPES = ("FACT", "EVENT", "ONTOLOGY", "ID", "ENTITY", "AGENT", "PROPERTY")
SET_TYPES = ("ENTITY", "FACT", "EVENT", "ONTOLOGY", "PROPERTY")


def fact_options(func: Any) -> Any:
    """Options naming a fact (subject, property, target and the rest of its key)."""
    for name, help_text in reversed(
        (
            ("--agent", "Agent holding the belief (default: the self agent)."),
            ("--subject", "Subject id ('NULL' = any)."),
            ("--property", "Property, e.g. IsOn."),
            ("--target", "Target id ('NULL' = any, empty = none)."),
            ("--sub-property", "Sub-property, e.g. 3D."),
            ("--subject-owner", "Owner of the subject (joints)."),
            ("--target-owner", "Owner of the target."),
        )
    ):
        func = click.option(name, help=help_text)(func)
    return func


def _self_agent(db: Database, agent: str | None) -> str:
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
@listing_options
@click.pass_obj
def get_info(
    app: Any, info_type: str, sub_type: str, fmt: str | None, limit: int | None, **opts: Any
) -> None:
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
    kind, sub = info_type.upper(), sub_type.upper()
    readers = READERS[kind]
    if sub not in readers:
        raise click.UsageError(f"unknown {kind} subtype {sub!r}: use one of {', '.join(readers)}")
    ask = Ask(
        app.db,
        opts,
        limit,
        parse_time_option(opts["at"], "--at"),
        parse_time_option(opts["since"], "--from"),
        parse_time_option(opts["until"], "--to"),
    )
    rows, empty = readers[sub](ask)
    emit(rows, fmt, limit=limit, empty=empty)


@dataclass(frozen=True)
class Ask:
    """One get-info request: the database, the options, the parsed times."""

    db: Database
    opts: dict[str, Any]
    limit: int | None
    at: int | None
    since: int | None
    until: int | None

    @property
    def key(self) -> dict[str, Any]:
        """The fact-key filters (subject, property, target, sub-property, owners)."""
        return {name: self.opts[name] for name in KEY_OPTIONS}

    def agent(self, *, self_by_default: bool = False) -> str | None:
        """``--agent`` (checked), or the self agent when asked to default to it."""
        agent = self.opts["agent"]
        if agent is None and self_by_default:
            agent = _self_agent(self.db, None)
        if agent:
            self.db.store().check_agent(agent)
        return agent

    def need(self, what: str, **flags: str) -> None:
        """A usage error unless every option (name=flag) was given."""
        if not all(self.opts[name] for name in flags):
            raise click.UsageError(f"{what} needs {' and '.join(flags.values())}")

    def without_at(self, what: str) -> None:
        if self.at is not None:
            raise click.UsageError(f"--at works with FACT CURRENT (beliefs as of TIME), not {what}")


Rows = tuple[Sequence[Any], str]
KEY_OPTIONS = ("subject", "property", "target", "sub_property", "subject_owner", "target_owner")
NO_ROWS = "(no rows)"


def _fact_value(ask: Ask) -> Rows:
    agent = ask.agent(self_by_default=True)
    ask.need("FACT VALUE", subject="--subject", property="--property")
    o = ask.opts
    row = _q().fact_value(
        ask.db,
        agent,
        o["subject"],
        o["property"],
        o["target"] or "",
        at=ask.at,
        sub_property=o["sub_property"],
        subject_owner=o["subject_owner"],
        target_owner=o["target_owner"],
    )
    return ([row] if row else []), "(the fact does not hold)"


def _fact_current(ask: Ask) -> Rows:
    if ask.at is not None:
        agent = ask.agent(self_by_default=True)
        return _q().beliefs_at(ask.db, agent, ask.at, **ask.key), NO_ROWS
    return _q().current_facts(ask.db, ask.agent(), limit=ask.limit, **ask.key), NO_ROWS


def _fact_old(ask: Ask) -> Rows:
    ask.without_at("FACT OLD")
    return _q().memory(
        ask.db, ask.agent(), since=ask.since, until=ask.until, limit=ask.limit, **ask.key
    ), NO_ROWS


def _fact_all(ask: Ask) -> Rows:
    ask.without_at("FACT ALL")
    return _q().history(
        ask.db, ask.agent(), since=ask.since, until=ask.until, limit=ask.limit, **ask.key
    ), NO_ROWS


def _events(ask: Ask) -> Rows:
    return _q().events(
        ask.db,
        ask.agent(),
        since=ask.since,
        until=ask.until,
        kind=ask.opts["kind"],
        limit=ask.limit,
        **ask.key,
    ), NO_ROWS


def _ontology(ask: Ask) -> Rows:
    return _q().ontology(ask.db), NO_ROWS


def _ontology_value(ask: Ask) -> Rows:
    ask.need("ONTOLOGY VALUE", entity_class="--class")
    return _q().ontology(ask.db, ask.opts["entity_class"]), NO_ROWS


def _ontology_leave(ask: Ask) -> Rows:
    ask.need("ONTOLOGY LEAVE", entity_class="--class")
    return _q().descendants(ask.db, ask.opts["entity_class"]), NO_ROWS


def _entities(ask: Ask) -> Rows:
    return _q().entities(ask.db, ask.opts["entity_id"], kind=ask.opts["kind"]), NO_ROWS


def _agents(ask: Ask) -> Rows:
    return _q().agents(ask.db), NO_ROWS


def _properties(ask: Ask) -> Rows:
    return _q().properties(ask.db, ask.opts["entity_id"], ask.opts["key"]), NO_ROWS


def _q() -> Any:
    """:mod:`toaster.queries`, imported when a command runs (``toaster --help`` stays fast)."""
    from toaster import queries

    return queries


#: get-info TYPE -> SUBTYPE -> the reader answering it
READERS: dict[str, dict[str, Callable[[Ask], Rows]]] = {
    "FACT": {"ALL": _fact_all, "CURRENT": _fact_current, "OLD": _fact_old, "VALUE": _fact_value},
    "EVENT": {"ALL": _events},
    "ONTOLOGY": {"ALL": _ontology, "VALUE": _ontology_value, "LEAVE": _ontology_leave},
    "ID": {"ALL": _entities, "VALUE": _entities},
    "ENTITY": {"ALL": _entities, "VALUE": _entities},
    "AGENT": {"ALL": _agents},
    "PROPERTY": {"ALL": _properties, "VALUE": _properties},
}


@click.command("set-info")
@click.argument(
    "info_type", metavar="TYPE", required=False, type=click.Choice(SET_TYPES, case_sensitive=False)
)
@click.option(
    "--file",
    "files",
    multiple=True,
    type=click.Path(dir_okay=False),
    help="A JSON/YAML batch or one of the original's XML seeds (repeatable; each "
    "file is one transaction).",
)
@click.option("--add/--remove", default=True, help="Add (default) or remove.")
@fact_options
@click.option("--id", "entity_id", help="Entity id (ENTITY, PROPERTY).")
@click.option("--name", default="", help="Entity name (default: the id).")
@click.option(
    "--type",
    "entity_kind",
    default="object",
    help="Entity kind: human, robot, object, joint, area...",
)
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
def set_info(
    app: Any, info_type: str | None, files: tuple[str, ...], add: bool, **opts: Any
) -> None:
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
    from toaster.db.seed import load_file

    store = app.db.store()
    for path in files:
        report = load_file(store, path)
        say(f"{path}: {', '.join(f'{n} {kind}' for kind, n in report.items()) or 'nothing'}")
    if not info_type:
        if files:
            return
        raise click.UsageError("give a TYPE (ENTITY, FACT, EVENT, ONTOLOGY, PROPERTY) or --file")
    opts["at"] = parse_time_option(opts["at"], "--at")
    say(WRITERS[info_type.upper()](store, add, opts))


def _set_entity(store: Store, add: bool, opts: dict[str, Any]) -> str:
    entity_id = _need(opts, "entity_id", "--id")
    if not add:
        store.remove_entity(entity_id)
        return f"entity {entity_id!r} removed"
    store.add_entity(
        entity_id,
        opts["entity_kind"],
        opts["name"],
        opts["owner"],
        is_self=opts["is_self"],
        t_ns=opts["at"],
    )
    return f"entity {entity_id!r} saved"


def _fact(opts: dict[str, Any]) -> Any:
    """The fact named by the options (``--value`` default 'true')."""
    from toaster.db.seed import fact_from_mapping

    _need(opts, "subject", "--subject")
    row = {
        k: opts[k]
        for k in (
            "subject",
            "property",
            "target",
            "sub_property",
            "subject_owner",
            "target_owner",
            "confidence",
            "observability",
            "property_type",
        )
        if opts[k] is not None
    }
    row["value"] = opts["value"] if opts["value"] is not None else "true"
    if opts["num"] is not None:
        row["num"] = opts["num"]
    return fact_from_mapping(row)


def _set_fact(store: Store, add: bool, opts: dict[str, Any]) -> str:
    agent = opts["agent"] or store.self_agent()
    _need(opts, "property", "--property")
    if not add:
        n = store.retract_facts(
            agent,
            opts["property"],
            opts["subject"],
            opts["target"],
            sub_property=opts["sub_property"],
            subject_owner_id=opts["subject_owner"],
            target_owner_id=opts["target_owner"],
            t_ns=opts["at"],
            actor=opts["actor"],
        )
        return f"{n} fact(s) ended for {agent}"
    outcome = store.assert_fact(agent, _fact(opts), t_ns=opts["at"], actor=opts["actor"])
    return f"fact {outcome} for {agent}"


def _set_event(store: Store, add: bool, opts: dict[str, Any]) -> str:
    agent = opts["agent"] or store.self_agent()
    _need(opts, "property", "--property")
    if not add:
        raise click.UsageError("an event cannot be removed: it happened")
    store.record_event(agent, _fact(opts), t_ns=opts["at"])
    return f"event recorded for {agent}"


def _set_ontology(store: Store, add: bool, opts: dict[str, Any]) -> str:
    entity_class = _need(opts, "entity_class", "--class")
    if not add:
        return f"{store.remove_ontology(entity_class, opts['individual'])} ontology row(s) removed"
    store.add_ontology(
        entity_class, _need(opts, "individual", "--individual"), opts["instantiated"]
    )
    return "ontology row saved"


def _set_property(store: Store, add: bool, opts: dict[str, Any]) -> str:
    from toaster.db.seed import property_value

    entity_id = _need(opts, "entity_id", "--id")
    if not add:
        return f"{store.remove_property(entity_id, opts['key'])} property row(s) removed"
    key = _need(opts, "key", "--key")
    store.set_property(entity_id, key, property_value(_need(opts, "value", "--value"), key))
    return "property saved"


#: set-info TYPE -> the writer doing it (returns the status line)
WRITERS: dict[str, Callable[[Any, bool, dict[str, Any]], str]] = {
    "ENTITY": _set_entity,
    "FACT": _set_fact,
    "EVENT": _set_event,
    "ONTOLOGY": _set_ontology,
    "PROPERTY": _set_property,
}


def _need(opts: dict[str, Any], name: str, flag: str) -> str:
    value = opts.get(name)
    if value in (None, ""):
        raise click.UsageError(f"missing {flag}")
    return str(value)
