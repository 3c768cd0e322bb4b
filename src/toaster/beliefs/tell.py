"""What is said: a speaker tells listeners (or everyone who hears) a fact.

A listener who trusts the speaker learns the fact (its own belief, source ``told:SPEAKER``);
for a place (a copresence or containment property: IsInRoom, IsIn, IsOn) it also stops
believing the subject is anywhere else. Everyone who hears the telling learns that too, at the
second order: when A hears B tell C, A's model of C (``A>C``) learns the fact if C trusts B
(the trust policy is shared knowledge), and A's model of the speaker (``A>B``) holds it.
Told beliefs are ordinary beliefs afterwards: a listener who later perceives the subject sees
what is true (seeing again), and perceived changes of the key replace them.

Trust (settings ``trust`` and ``distrust``): ``everyone`` (default) believes every speaker but
those in ``distrust``; ``witnesses`` believes a speaker only if the speaker perceived the
subject later than the listener did (its last belief change about the subject is more recent).
Hearers of a public telling are the agents in the speaker's room, as the self agent sees it.
A fact told without a sub-property takes the one the self agent's facts of that property use
(IsInRoom's ``room`` from the areas producer): the listener's belief is then the key the robot
holds and perceives, not a second key that read as a false belief beside the true one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from sqlalchemy import Connection, text

from toaster.errors import InvalidInputError
from toaster.model import Fact, check_fact, check_id, check_list
from toaster.rules import settings as cfg
from toaster.rules.hook import holder_id
from toaster.timeutil import check_ns, now_ns

if TYPE_CHECKING:
    from toaster.db.database import Database
    from toaster.db.writer.store import Store

#: The property of the self agent's point events recording a telling (one per listener).
TELLS = "Tells"


def tell(
    db: Database,
    speaker: str,
    fact: Fact,
    *,
    listeners: Sequence[str] | None = None,
    t_ns: int | None = None,
) -> list[str]:
    """``speaker`` tells ``fact`` to ``listeners`` (None: everyone in its room) at ``t_ns``
    (default now), in one transaction; returns the holders that learnt it."""
    fact = check_fact(fact)
    t = now_ns() if t_ns is None else check_ns(t_ns)
    check_id(speaker, "speaker")
    if listeners is not None:
        listeners = [check_id(who, "listener") for who in check_list(listeners, "listeners")]
    store = db.store()
    with store.transaction() as conn:
        agents = store.agents()
        for who in (speaker, *(listeners or ())):
            if who not in agents or ">" in who:
                msg = (
                    f"unknown agent {who!r} in a telling: speakers and listeners are "
                    "registered agents (toaster set-info ENTITY --id ID --type human)"
                )
                raise InvalidInputError(msg)
        settings = cfg.read(conn)
        self_id = _self_or_none(agents)
        if listeners is None and self_id is None:
            msg = (
                "a public telling needs the rooms of the one self agent, and there is not "
                "exactly one: name the listeners"
            )
            raise InvalidInputError(msg)
        heard = (
            list(listeners)
            if listeners is not None
            else _in_room_with(conn, self_id or "", speaker, settings["copresence"], t)
        )
        hearers = sorted({speaker, *heard})
        told = [who for who in sorted(set(heard)) if who != speaker]
        trusting = {who: _trusts(conn, settings, who, speaker, fact.subject_id, t) for who in told}
        learners = [who for who in told if trusting[who]]
        if settings["depth"] >= 2:
            learners += [holder_id(a, c) for a in hearers for c in told if a != c and trusting[c]]
            learners += [holder_id(a, speaker) for a in hearers if a != speaker]
        holders = set(conn.execute(text("SELECT id FROM holders")).scalars())  # the rule's own
        learners = [h for h in dict.fromkeys(learners) if h in holders]
        if self_id is not None and not fact.sub_property:
            fact = _as_the_self_says(conn, self_id, fact)
        places = {*settings["copresence"], *settings["containment"]}
        for holder in learners:
            _learn(store, conn, holder, fact, t, f"told:{speaker}", fact.property in places)
        if self_id is not None:  # the robot remembers who told whom what
            for listener in told or [""]:
                store.record_event(
                    self_id, Fact(speaker, TELLS, listener, _said(fact)), t_ns=t, source="tell"
                )
    return learners


def _as_the_self_says(conn: Connection, self_id: str, fact: Fact) -> Fact:
    """``fact`` with the sub-property of the self agent's key of the same subject, property and
    target, else the one sub-property its keys of that property all use (else unchanged)."""
    subs = conn.execute(
        text(
            "SELECT sub_property, MAX(CASE WHEN subject_id = :s AND target_id = :t "
            "AND subject_owner_id = :so AND target_owner_id = :to THEN 1 ELSE 0 END) "
            "FROM fact_keys WHERE agent_id = :a AND property = :p GROUP BY sub_property"
        ),
        {
            "a": self_id,
            "p": fact.property,
            "s": fact.subject_id,
            "t": fact.target_id,
            "so": fact.subject_owner_id,
            "to": fact.target_owner_id,
        },
    ).all()
    same_key = [sub for sub, same in subs if same]
    if len(same_key) == 1:
        return fact._replace(sub_property=same_key[0])
    if len(subs) == 1:
        return fact._replace(sub_property=subs[0][0])
    return fact


def _said(fact: Fact) -> str:
    return " ".join(
        p
        for p in (
            fact.subject_id,
            fact.property,
            fact.target_id,
            fact.value_text if fact.value_text != "true" else "",
        )
        if p
    )


def _self_or_none(agents: dict[str, bool]) -> str | None:
    selves = [a for a, is_self in agents.items() if is_self]
    return selves[0] if len(selves) == 1 else None


def _in_room_with(
    conn: Connection, self_id: str, speaker: str, rooms: list[str], t: int
) -> list[str]:
    """The agents the self agent believes, at ``t``, in a room with ``speaker``."""
    if not rooms:
        return []
    marks = ", ".join(f":p{i}" for i in range(len(rooms)))
    params: dict[str, Any] = {f"p{i}": p for i, p in enumerate(rooms)}
    held = (
        f"SELECT k.subject_id, k.target_id FROM fact_keys k JOIN facts f ON f.key_id = k.id "
        f"WHERE k.agent_id = :self AND k.property IN ({marks}) AND f.value_text = 'true' "
        f"AND f.valid_from_ns <= :t AND (f.valid_to_ns IS NULL OR f.valid_to_ns > :t)"
    )
    rows = conn.execute(
        text(
            f"WITH at_t AS ({held}) SELECT DISTINCT o.subject_id FROM at_t s "
            f"JOIN at_t o ON o.target_id = s.target_id JOIN agents a ON a.id = o.subject_id "
            f"WHERE s.subject_id = :speaker AND NOT a.is_self"
        ),
        {**params, "self": self_id, "t": t, "speaker": speaker},
    ).scalars()
    return list(rows)


def _last_news(conn: Connection, holder: str, subject: str, t: int) -> int:
    """When ``holder`` last saw a change about ``subject`` (at or before ``t``; what it was
    told does not count)."""
    found = conn.execute(
        text(
            "SELECT MAX(stamp_ns) FROM event_log WHERE agent_id = :h AND subject_id = :s "
            "AND stamp_ns <= :t AND kind <> 'event' AND source NOT LIKE 'told:%'"
        ),
        {"h": holder, "s": subject, "t": t},
    ).scalar()
    return -1 if found is None else int(found)


def _trusts(
    conn: Connection, settings: dict[str, Any], listener: str, speaker: str, subject: str, t: int
) -> bool:
    if speaker in settings["distrust"]:
        return False
    if settings["trust"] == "witnesses":
        return _last_news(conn, speaker, subject, t) > _last_news(conn, listener, subject, t)
    return True


def _learn(
    store: Store, conn: Connection, holder: str, fact: Fact, t: int, source: str, place: bool
) -> None:
    """``holder`` believes ``fact`` from ``t``; a place replaces the others of the subject."""
    if place:
        others = conn.execute(
            text(
                "SELECT DISTINCT k.target_id FROM current_facts k WHERE k.agent_id = :h "
                "AND k.subject_id = :s AND k.property = :p AND k.target_id <> :tg"
            ),
            {"h": holder, "s": fact.subject_id, "p": fact.property, "tg": fact.target_id},
        ).scalars()
        for target in list(others):
            store.retract_facts(
                holder, fact.property, fact.subject_id, target, t_ns=t, source=source
            )
    store.assert_fact(holder, fact, t_ns=t, source=source, strict=False)
