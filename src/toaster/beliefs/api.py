"""Reading beliefs: an agent's (or A's model of B's) beliefs, one value, false-belief reports,
the history of one belief across agents. Plain queries over the same tables as the world state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

from sqlalchemy import text

from toaster import queries as q
from toaster.db import catalog
from toaster.errors import InvalidInputError
from toaster.model import FactRow, check_id, check_list
from toaster.rules import settings as cfg
from toaster.rules.hook import holder_id

if TYPE_CHECKING:
    from toaster.db.database import Database


class BeliefDiff(NamedTuple):
    """One key on which two holders disagree; ``None`` = not believed by that holder."""

    subject_id: str
    property: str
    target_id: str
    sub_property: str
    value_a: str | None
    confidence_a: float | None
    value_b: str | None
    confidence_b: float | None


def _holder(db: Database, agent: str, about: str | list[str] | tuple[str, ...] | None) -> str:
    chain = (
        [] if about is None else ([about] if isinstance(about, str) else check_list(about, "about"))
    )
    holder = holder_id(check_id(agent, "agent id"), *(check_id(a, "about") for a in chain))
    with db.transaction() as conn:
        found = conn.execute(text("SELECT 1 FROM holders WHERE id = :a"), {"a": holder}).first()
    if found is None:
        what = f"belief holder {holder!r}" if chain else f"agent {agent!r}"
        msg = f"unknown {what}: register the agents as humans or robots" + (
            " and raise the beliefs depth (`toaster beliefs config depth N`)" if chain else ""
        )
        raise InvalidInputError(msg)
    return holder


def self_agent(db: Database) -> str:
    """The robot whose beliefs others are compared with: the one self agent (an error asks
    to name it when there are several or none)."""
    return db.store().self_agent(
        fix="name the robot to compare with (other=ID; on the command line --other ID)"
    )


def beliefs(
    db: Database,
    agent: str,
    about: str | list[str] | None = None,
    *,
    at: int | None = None,
    **filters: Any,
) -> list[FactRow]:
    """What ``agent`` believes (or believes ``about`` believes) now, or at time ``at``."""
    holder = _holder(db, agent, about)
    if at is None:
        return q.current_facts(db, holder, **filters)
    return q.beliefs_at(db, holder, at, **filters)


def belief_value(
    db: Database,
    agent: str,
    subject: str,
    property: str,
    target: str = "",
    *,
    about: str | list[str] | None = None,
    at: int | None = None,
) -> FactRow | None:
    """One belief of ``agent`` (or of its model of ``about``) now or at ``at``; None if not held."""
    return q.fact_value(db, _holder(db, agent, about), subject, property, target, at=at)


def false_beliefs(
    db: Database,
    agent: str,
    other: str | None = None,
    *,
    about: str | None = None,
    at: int | None = None,
) -> list[BeliefDiff]:
    """Keys on which ``agent`` (A) and ``other`` (B, default the self agent) disagree: A believes
    what B does not, B believes what A does not, or both hold the key with different values."""
    a_rows = beliefs(db, agent, about, at=at)
    b_rows = beliefs(db, other or self_agent(db), at=at)

    def index(rows: list[FactRow]) -> dict[tuple[str, ...], FactRow]:
        return {
            (
                r.subject_id,
                r.subject_owner_id,
                r.property,
                r.sub_property,
                r.target_id,
                r.target_owner_id,
            ): r
            for r in rows
        }

    a, b = index(a_rows), index(b_rows)
    diffs = []
    for key in sorted(a.keys() | b.keys()):
        ra, rb = a.get(key), b.get(key)
        if ra is not None and rb is not None and ra.value_text == rb.value_text:
            continue
        diffs.append(
            BeliefDiff(
                key[0],
                key[2],
                key[4],
                key[3],
                ra.value_text if ra else None,
                ra.confidence if ra else None,
                rb.value_text if rb else None,
                rb.confidence if rb else None,
            )
        )
    return diffs


def belief_history(
    db: Database,
    subject: str,
    property: str,
    target: str | None = None,
    *,
    agents: list[str] | None = None,
) -> list[FactRow]:
    """Every interval of one belief across holders (self, agents, nested), oldest first."""
    rows = q.history(db, agents, subject=subject, property=property, target=target)
    return sorted(rows, key=lambda r: (r.valid_from_ns, r.agent_id))


def holders(db: Database) -> list[str]:
    """Every non-self belief holder, first order then nested (``A>B``), by depth and id."""
    with db.transaction() as conn:
        rows = conn.execute(
            text(
                "SELECT h.id FROM holders h LEFT JOIN agents a ON a.id = h.agent_id "
                "WHERE a.is_self IS NULL OR NOT a.is_self ORDER BY h.depth, h.id"
            )
        ).all()
    return [r[0] for r in rows]


def configure(db: Database, **settings: Any) -> dict[str, Any]:
    """Change belief-rule settings (validated); return the whole configuration."""
    store = db.store()
    for key, value in settings.items():
        store.put_setting(cfg.SCOPE, key, cfg.validate(key, value))
    return config(db)


def reset(db: Database, *keys: str) -> dict[str, Any]:
    """Put settings back to their defaults (all of them when no key is given)."""

    with db.store().transaction() as conn:
        for key in keys or (None,):
            catalog.delete_setting(conn, cfg.SCOPE, key and cfg.check_key(key))
    return config(db)


def config(db: Database) -> dict[str, Any]:
    """The belief-rule configuration as stored (defaults filled in)."""
    with db.transaction() as conn:
        return cfg.read(conn)
