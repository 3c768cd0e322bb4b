"""The belief rule as one pipeline of the database's own triggers, for every writer.

:data:`PIPELINE` declares, once, which steps (templates of ``rules/sql``) run and under
which conditions. It is rendered per backend into triggers on ``belief_runs``, one unit per
step instance (see :mod:`toaster.rules.triggers`):

- PostgreSQL: a row trigger running the plpgsql function ``toaster_belief_run()``, one ``IF``
  per block, calling a function ``toaster_step_<unit>`` per step;
- SQLite: a row trigger on ``belief_runs`` and one trigger per block on ``belief_steps`` (a
  block runs when its row is inserted, and its condition is that insert's ``WHERE``), with
  the statements of its steps inlined when installed.

A writer starts a run by filling ``belief_changed`` with the self keys it changed, then
inserting ``(self_id, t_ns, recorded_ns)`` into ``belief_runs`` (the row is never kept): the
store does so for the library (:class:`toaster.rules.hook.BeliefRule`) and the trigger of
``fact_inbox`` for plain SQL clients, so both get the same intervals, events and beliefs in
their own transaction. Inside the triggers the steps' parameters are the run's columns
(``:self`` is ``NEW.self_id``, ``:t`` ``NEW.t_ns``, ``:recorded`` ``NEW.recorded_ns``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: The run's columns the steps read, by parameter name; :data:`Step` adds constants.
RUN_PARAMS = {
    "self": "NEW.self_id",
    "t": "NEW.t_ns",
    "recorded": "NEW.recorded_ns",
    "source": "'beliefs'",
}
AROUND = {"phase": "'around'", "everything": "0"}


@dataclass(frozen=True)
class Step:
    """One template of ``rules/sql`` with constant parameters (20_perceive's phase)."""

    name: str
    constants: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Block:
    """Steps and nested blocks run in order when ``condition`` (SQL over the run, None:
    always) holds when the block is reached."""

    name: str
    condition: str | None
    body: tuple[Step | Block, ...]


def _steps(*names: str, **constants: str) -> tuple[Step, ...]:
    return tuple(Step(name, tuple(sorted(constants.items()))) for name in names)


#: The run applies: rules enabled, a self agent's change, somebody else to hold beliefs.
#: Several robots may write one database: each keeps its own world view, and the holders
#: take the changes whichever robot perceives them (one timeline: see :data:`CLOCK`).
RUNS = (
    "{{setting(enabled)}} = 'true' "
    "AND EXISTS (SELECT 1 FROM agents WHERE id = NEW.self_id AND is_self) "
    "AND EXISTS (SELECT 1 FROM agents WHERE NOT is_self) "
    "AND EXISTS (SELECT 1 FROM belief_changed)"
)
#: Whom a robot's run may change (revision 0028): the holders whose chain's agents its facts
#: name (subject or target of one of its keys) or which act in its changes (a holder perceives
#: only what its agents perceive in the run's self facts, and an actor its own changes), and
#: the holders following one of its changed keys; and the robot's own row (revision 0031): its
#: runs take turns on it, so that a run never reads a self fact later than its time (a
#: producer's run that names nobody, as a first tick of things, moved no clock, and another
#: producer's run of the same robot at an earlier time then took, at that time, a fact that
#: began after it: an event no interval began at). The runs of robots whose people never meet
#: change disjoint sets: each takes its own holders' clocks (below) and never waits for the
#: other's; runs that share a holder take turns on its clock.
_NAMED = (
    "({m} IN (SELECT actor_id FROM belief_changed WHERE actor_id IS NOT NULL) "
    "OR EXISTS (SELECT 1 FROM fact_keys k WHERE k.subject_id = {m} AND k.agent_id = NEW.self_id) "
    "OR EXISTS (SELECT 1 FROM fact_keys k WHERE k.target_id = {m} AND k.agent_id = NEW.self_id))"
)
MINE = (
    "SELECT h.id FROM holders h WHERE h.id = NEW.self_id OR (h.depth = 1 AND "
    + _NAMED.format(m="h.id")
    + ") OR (h.depth >= 2 AND NOT EXISTS (SELECT 1 FROM belief_chain c "
    "WHERE c.holder_id = h.id AND NOT "
    + _NAMED.format(m="c.member_id")
    + ")) OR EXISTS (SELECT 1 FROM belief_changed b JOIN belief_follow w ON w.self_key = b.key_id "
    "AND w.holder_id = h.id AND w.to_ns IS NULL)"
)
#: The rules' clock is per holder (``holders.clock_ns``, ``clock_self``; revision 0028, before
#: it one row of ``store_state``). A run that applies first moves the clocks of its holders
#: (:data:`MINE`, ``{mine}``: a condition on ``id``) to its time unless it is behind one of
#: them: a robot or producer whose clock lags another's (or a late SQL writer) never writes a
#: holder's row before one already written (the store also writes the self agents' own facts
#: at the latest clock's time: Store._writes). A run at a holder's clock whose self agent set
#: it (``clock_self``) shares its instant: one robot's writes at one time reach the holders at
#: that time. Any other run at or behind a clock takes the instant after it: two robots' runs
#: never share an instant of a holder (they could take its key in and out at one time;
#: revision 0015). The run's time is the latest of its holders' so moved, and every one of
#: them takes it (:data:`CLOCK_NS`: the clocks agree after :data:`CLOCK`). On PostgreSQL
#: the run first locks its holders' rows, in the order of their ids: runs that share a holder
#: take turns, and each sees the rows of the runs committed before it.
CLOCK = (
    "UPDATE holders SET clock_ns = CASE "
    "WHEN clock_ns IS NULL OR NEW.t_ns > clock_ns THEN NEW.t_ns "
    "WHEN NEW.t_ns = clock_ns AND clock_self = NEW.self_id THEN clock_ns "
    "ELSE clock_ns + 1 END WHERE {mine}",
    "UPDATE holders SET clock_ns = (SELECT MAX(x.clock_ns) FROM holders x WHERE x.{mine}), "
    "clock_self = NEW.self_id WHERE {mine}",
)
CLOCK_NS = "COALESCE((SELECT MAX(x.clock_ns) FROM holders x WHERE x.{mine}), NEW.t_ns)"
#: The agents (or the depth) changed since the nested holders were last registered, and
#: somebody perceives something (a database where nobody does keeps only its real agents).
NEW_AGENTS = (
    "CAST({{setting(depth)}} AS INTEGER) >= 2 AND EXISTS (SELECT 1 FROM belief_seen) "
    "AND {{holders_basis}} <> (SELECT holders_basis FROM store_state WHERE id = 1)"
)
#: The holders step registered somebody: perceive again with them.
HOLDERS_ADDED = "EXISTS (SELECT 1 FROM belief_new_chain)"
#: A change of who perceives what (rooms, containers, visibility, closed containers): look
#: before and after the tick, for everything, to find what is seen again.
PERCEPTION_CHANGED = (  # (each changed key's property looked up by its id: a join was
    # planned as a scan of every key of the database; docs/beliefs.md)
    "EXISTS (SELECT 1 FROM belief_changed b "
    "WHERE (SELECT k.property FROM fact_keys k WHERE k.id = b.key_id) IN ({{perception}}))"
)
#: A holder takes a change (or sees something again), or follows a changed key: when nobody
#: perceives anything, as in a crowd replay with no rooms, the write steps are skipped.
ANY_WORK = (
    "EXISTS (SELECT 1 FROM belief_in) OR EXISTS (SELECT 1 FROM belief_changed b "
    "{{pinned_join}} belief_follow w ON w.self_key = b.key_id AND w.to_ns IS NULL)"
)
SHARE_ROWS = "{{setting(share_rows)}} = 'true'"
#: A holder's perception confidence of a followed key changed (rare: not on a first tick, when
#: PostgreSQL, with no statistics yet, once planned these updates as a scan per row).
REPCONF = "EXISTS (SELECT 1 FROM belief_todo WHERE action = 'repconf')"

#: The groups of holders (96_regroup) hold for this run: formed for this self agent, and no
#: perception changes (nor an actor, who perceives its own change alone). Any other run first
#: ends them (15_ungroup) and forms them again at its end.
STEADY = (
    "COALESCE((SELECT groups_for FROM store_state WHERE id = 1), '') = NEW.self_id "
    f"AND NOT ({PERCEPTION_CHANGED}) "
    "AND NOT EXISTS (SELECT 1 FROM belief_changed WHERE actor_id IS NOT NULL)"
)
#: No other robot (self agent) is registered: the groups of holders and the kept perception
#: are one robot's, in ``store_state`` (revisions 0011, 0023). With several, each robot's run
#: would end what another's formed (and write ``store_state``, which every run would then wait
#: for): they keep neither, and their runs compute perception (revision 0028).
ONE_ROBOT = "NOT EXISTS (SELECT 1 FROM agents WHERE is_self AND id <> NEW.self_id)"
#: The groups were ended (by this run, or by a write since the last run), and one robot runs
#: the rules.
REGROUP = f"{{{{groups_ended}}}} AND {ONE_ROBOT}"
#: A run that is not :data:`STEADY` ends the groups and the kept perception, if any are left
#: (a database with several robots keeps none: its runs write no ``store_state``).
ENDS_GROUPS = (
    f"NOT ({STEADY}) AND NOT ({{{{groups_ended}}}} "
    "AND (SELECT perceived_for FROM store_state WHERE id = 1) IS NULL "
    "AND NOT EXISTS (SELECT 1 FROM belief_groups))"
)
NO_ACTOR = "NOT EXISTS (SELECT 1 FROM belief_changed WHERE actor_id IS NOT NULL)"
#: The kept perception (``belief_perceived``, 21_remember) is this self agent's.
KEPT = "COALESCE((SELECT perceived_for FROM store_state WHERE id = 1), '') = NEW.self_id"
#: A steady run whose time the kept perception holds for: it is what 20_perceive would compute
#: (no perception input changed since it was kept: a run with one, a write that ends the
#: groups, a change of agents or settings ends it) and this run reuses it (20_reuse).
REUSE = (
    f"{STEADY} AND {KEPT} "
    "AND COALESCE((SELECT perceived_ns FROM store_state WHERE id = 1), NEW.t_ns + 1) <= NEW.t_ns"
)
#: A steady run that keeps no perception computes it for every located entity and keeps it,
#: when no perception fact starts or ends at its time or later (then perceiving around the
#: tick is perceiving after it).
REMEMBER = (
    f"{STEADY} AND NOT ({REUSE}) "
    "AND COALESCE({{perception_horizon(NEW.self_id)}}, NEW.t_ns - 1) < NEW.t_ns"
)
#: A run that changed perception keeps what it perceives after the tick (for every holder:
#: the groups are ended), unless an actor perceived its own change there, or a perception
#: fact starts or ends after the run's time, or another robot runs the rules (:data:`ONE_ROBOT`).
REMEMBER_AFTER = (
    f"{NO_ACTOR} AND COALESCE({{{{perception_horizon(NEW.self_id)}}}}, NEW.t_ns) <= NEW.t_ns "
    f"AND {ONE_ROBOT}"
)
#: Steady runs drop the settled keys (98_settle) from their changes, unless nested holders
#: are still to be registered (NEW_AGENTS would run for them).
SETTLED = (
    f"{REUSE} AND (CAST({{{{setting(depth)}}}} AS INTEGER) < 2 "
    "OR {{holders_basis}} = (SELECT holders_basis FROM store_state WHERE id = 1))"
)
#: Something is left to do: a change that is not settled.
WORK = "EXISTS (SELECT 1 FROM belief_changed)"

PIPELINE = Block(
    "run",
    RUNS,
    (
        Block("settled", SETTLED, _steps("19_settled")),
        Block(
            "work",
            WORK,
            (
                *_steps("10_focus", "12_moves", "13_late", "58_frozen"),
                Block("not_steady", ENDS_GROUPS, _steps("15_ungroup")),
                Block(
                    "remember",
                    REMEMBER,
                    (
                        *_steps("20_perceive", phase="'after'", everything="1"),
                        *_steps("21_remember"),
                    ),
                ),
                Block("reuse", REUSE, _steps("20_reuse")),
                Block("perceive", f"NOT ({REUSE})", _steps("20_perceive", **AROUND)),
                *_steps("30_changes", moves="0"),
                *_steps("32_expand"),
                Block(
                    "new_agents",
                    NEW_AGENTS,
                    (
                        *_steps("holders"),
                        Block(
                            "holders_added",
                            HOLDERS_ADDED,
                            (
                                *_steps("reperceive"),
                                *_steps("20_perceive", **AROUND),
                                *_steps("30_changes", moves="0"),
                            ),
                        ),
                        *_steps("holders_seen"),
                    ),
                ),
                Block(
                    "phases",
                    PERCEPTION_CHANGED,
                    (
                        *_steps("20_perceive", phase="'before'", everything="1"),
                        *_steps("20_perceive", phase="'after'", everything="1"),
                        *_steps("30_changes", moves="1"),
                        *_steps("40_refresh", "42_keep_max"),
                        Block("remember_after", REMEMBER_AFTER, _steps("21_remember")),
                    ),
                ),
                Block(
                    "write",
                    ANY_WORK,
                    (
                        *_steps(
                            "35_freeze",
                            "45_resolve",
                            "50_keys",
                            "45_resolve",
                            "55_switch",
                            "58_frozen",
                            "60_plan",
                            "70_events",
                            "80_close",
                            "85_refresh_rows",
                        ),
                        Block("follow", SHARE_ROWS, _steps("90_follow")),
                        Block("own", f"NOT ({SHARE_ROWS})", _steps("91_open")),
                        Block("repconf", REPCONF, _steps("92_repconf")),
                        *_steps("94_keep_groups", "97_unsettle"),
                    ),
                ),
                Block("settle", KEPT, _steps("98_settle")),
            ),
        ),
        Block("regroup", REGROUP, _steps("96_regroup")),
    ),
)

_PARAM = re.compile(r"(?<![:\w]):([a-z_]+)")


def bind(sql: str, params: dict[str, str]) -> str:
    """``sql`` with its ``:name`` parameters replaced by SQL expressions (unknown: error)."""

    def value(match: re.Match[str]) -> str:
        name = match.group(1)
        if name not in params:
            msg = f"no value for parameter :{name} inside a trigger"
            raise ValueError(msg)
        return params[name]

    return _PARAM.sub(value, sql)


def statements(sql: str) -> list[str]:
    """The statements of rendered SQL (``--`` comment lines dropped)."""
    lines = [line for line in sql.splitlines() if not line.lstrip().startswith("--")]
    return [part.strip() for part in "\n".join(lines).split(";") if part.strip()]


def blocks(block: Block = PIPELINE) -> list[Block]:
    """``block`` and the blocks nested in it, outermost first."""
    found = [block]
    for part in block.body:
        if isinstance(part, Block):
            found += blocks(part)
    return found
