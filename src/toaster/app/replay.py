"""Recordings that come back whole: what ``toaster run --record`` adds to a recording
(:class:`~toaster.world.recorded.RunInfo`, the world at every tick) and how ``toaster run`` on
such a recording sets the run up as the recorded one was: the same self agent, belief holders,
thresholds, producers, areas and belief settings (``docs/recordings.md``, "Replaying").
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from toaster.world.recorded import RunInfo, WorldReplay, world_entities

if TYPE_CHECKING:
    from toaster.db import Database
    from toaster.producers import Session


def run_info(session: Session, db: Database | None, end_ns: int, rate_hz: float) -> RunInfo:
    """How ``session`` is set up, for ``/toaster/run``: its self agent, holders, thresholds
    (``spatial`` set when the spatial producer runs), areas, entities, the store's belief
    settings, the run's end and tick rate (that of its grid, or of its gaps)."""
    config = dict(session.config)
    if any(p.name == "move3d_facts" for p in session.producers):
        config["spatial"] = True
    return RunInfo(
        session.start_ns,
        end_ns,
        session.self_id,
        session.belief_holders,
        config,
        {area_id: dict(spec) for area_id, spec in session.areas.items()},
        world_entities(session.world),
        belief_settings(db) if db is not None else {},
        session.agent_views,
        rate_hz,
    )


def belief_settings(db: Database) -> dict[str, Any]:
    """The belief settings ``db`` stores (those that differ from the defaults)."""
    from toaster.db import catalog
    from toaster.rules.settings import SCOPE

    with db.transaction() as conn:
        return catalog.settings(conn, SCOPE)


def as_recorded(
    session: Session,
    *,
    holders: str | None,
    config: Mapping[str, Any] | None,
) -> Session:
    """``session`` set up as the recorded run was, when its source is a recorded world
    (``--holders`` and ``--config`` still win); any other session as it is."""
    from dataclasses import replace

    from toaster.producers.registry import builtin_producers
    from toaster.world.config import make_config, overlay_config

    source = session.sources[0] if session.sources else None
    if not isinstance(source, WorldReplay):
        return session
    info = source.info
    cfg = overlay_config(info.config, config) if config else dict(info.config)
    make_config(cfg)
    return replace(
        session,
        producers=builtin_producers(cfg, session.areas, spatial=bool(cfg.get("spatial"))),
        self_id=info.self_id or session.self_id,
        start_ns=info.start_ns,
        config=cfg,
        belief_holders=info.holders if holders is None else session.belief_holders,
        agent_views=info.agent_views,
    )


def apply_settings(session: Session, db: Database) -> list[str]:
    """Give ``db`` the recorded run's belief settings when it has none of its own; returns a
    note when it keeps different ones."""
    source = session.sources[0] if session.sources else None
    if not isinstance(source, WorldReplay) or not source.info.settings:
        return []
    from toaster.beliefs import configure

    mine = belief_settings(db)
    if not mine:
        configure(db, **source.info.settings)
        return []
    if mine != source.info.settings:
        return [
            f"{source.name}: the database's belief settings are kept, not the recording's "
            f"({source.info.settings}); beliefs may differ from the recorded run's"
        ]
    return []


def old_recording_note(path: Path, session: Session) -> list[str]:
    """A one-line note for a toaster recording made before ``/toaster/run`` (replayed from
    pdg's lists, not whole)."""
    source = session.sources[0] if session.sources else None
    if source is None or isinstance(source, WorldReplay) or not getattr(source, "toaster", False):
        return []
    return [
        f"{path.name}: a toaster recording without /toaster/run and /toaster/world (an older "
        "one, or one of toaster record): replayed from pdg's lists, without sizes, shape roles, "
        "lids, held objects, belief holders or its self agent (facts go to 'toaster'); "
        "record the run again to replay it whole"
    ]
