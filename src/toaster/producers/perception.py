"""pdg facts: isPresent for perceived agents and IsInHand for held objects; who moves what."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.world.config import DEFAULTS, make_config, ns
from toaster.world.state import JOINT, OBJECT, ROBOT, World


class PerceptionFacts:
    """isPresent (humans and robots perceived within ``presence_timeout``) and IsInHand."""

    name = "pdg"

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = make_config(config)

    def compute(self, world: World, t_ns: int) -> list[Fact]:
        """Facts for this tick."""
        return self.compute_batch(world, t_ns).facts()

    def compute_batch(self, world: World, t_ns: int) -> FactBatch:
        """Facts for this tick, as arrays."""
        cfg, n = self.config, world.n
        out = FactBatch(world)
        live = world.live_mask(t_ns, ns(cfg, "presence_timeout"))
        agents = np.flatnonzero(live & (world.kind[:n] <= ROBOT))
        out.add(
            "isPresent",
            agents,
            "",
            conf=cfg["confidence_present"],
            obs=cfg["observability_present"],
        )
        held = np.flatnonzero(live & (world.held_by[:n] >= 0))
        if held.size:
            agent = world.owner[world.held_by[held]]
            out.add(
                "IsInHand",
                held,
                agent,
                obs=cfg["observability_in_hand"],
                property_type="position",
                sub_property="object",
                tgt_owner=agent,
            )
        return out


class HandActors:
    """Who made a tick's changes of where things are: the agent holding or handling the thing.

    An object in an agent's hand (``put_in_hand``) is moved by that agent: the facts about
    where it is (``property_type`` position: IsInRoom, IsAt, IsInArea, IsIn, IsOn, IsNextTo)
    that change while it is held, or in the tick it is released, were made by the holder; an
    IsInHand fact is made by its target, the hand's agent (put in, removed, handed over). An
    object that moved (more than ``moved`` metres since the last tick) without being held, with
    an agent's hand joint (a joint whose name contains "hand") within ``reach`` metres of where
    it is now, was moved by the agent of the nearest such hand. The runner hands
    :meth:`actor_of` to the store, whose belief rule lets the actor perceive its changes
    wherever it is (docs/beliefs.md, the actor).
    """

    def __init__(
        self, reach: float = DEFAULTS["actor_hand_reach"], moved: float = DEFAULTS["actor_moved"]
    ) -> None:
        self.reach, self.moved = float(reach), float(moved)
        self._held = np.zeros(0, np.int64)  # world.held_by at the last update
        self._pos = np.zeros((0, 3))  # world.pos at the last update
        self.movers: dict[str, str] = {}  # object id -> the agent moving it this tick

    @staticmethod
    def _padded(before: np.ndarray, n: int, fill: object) -> np.ndarray:
        if len(before) == n:
            return before
        extra = np.full((max(n - len(before), 0), *before.shape[1:]), fill)
        return np.concatenate([before[:n], extra])

    def update(self, world: World) -> dict[str, str]:
        """Note who holds what after this tick's world commit; return the movers: objects
        held now (by their holder) or released since the last update (by who held them), and
        objects moved next to a hand (by the hand's agent)."""
        n = world.n
        now, pos = world.held_by[:n], world.pos[:n]
        before = self._padded(self._held, n, -1)
        pos_before = self._padded(self._pos, n, np.nan)
        self._held, self._pos = now.copy(), pos.copy()
        ids, owner = world.ids, world.owner
        self.movers = {}
        rows = np.flatnonzero((now >= 0) | (before >= 0))
        if rows.size:
            hands = np.where(now[rows] >= 0, now[rows], before[rows])
            self.movers = {
                ids[r]: ids[a]
                for r, a in zip(rows.tolist(), owner[hands].tolist(), strict=True)
                if a >= 0
            }
        self._handled(world, pos, pos_before, rows)
        return self.movers

    def _handled(
        self, world: World, pos: np.ndarray, pos_before: np.ndarray, held: np.ndarray
    ) -> None:
        """Objects that moved, not held, with a hand within reach: moved by that hand."""
        n = world.n
        objects = world.kind[:n] == OBJECT
        objects[held] = False
        step = np.linalg.norm(pos - pos_before, axis=1)
        moved = np.flatnonzero(objects & world.active[:n] & (step > self.moved))
        if not moved.size:
            return
        joints = np.flatnonzero((world.kind[:n] == JOINT) & world.active[:n])
        joints = np.array(
            [
                j
                for j in joints.tolist()
                if "hand" in world.joint_names[j].lower() and world.owner[j] >= 0
            ],
            dtype=np.int64,
        )
        if not joints.size:
            return
        gap = np.linalg.norm(pos[moved][:, None, :] - pos[joints][None, :, :], axis=2)
        nearest = gap.argmin(axis=1)
        for row, j, d in zip(
            moved.tolist(),
            nearest.tolist(),
            gap[np.arange(len(moved)), nearest].tolist(),
            strict=True,
        ):
            if d <= self.reach:
                self.movers.setdefault(world.ids[row], world.ids[int(world.owner[joints[j]])])

    def actor_of(self, agents: Mapping[str, bool]) -> Callable[[Fact], str | None] | None:
        """The actor of each changed fact of this tick (see :func:`actors_of`)."""
        return actors_of(self.movers, agents)


def actors_of(
    movers: Mapping[str, str], agents: Mapping[str, bool]
) -> Callable[[Fact], str | None] | None:
    """The actor of each changed fact of a tick whose :attr:`HandActors.movers` were
    ``movers`` (None: nothing is held or released). A tick's movers are a dict of their own
    (the next update makes a new one), so a writer thread may use them after the next tick.

    ``agents``: the store's holders (id -> is self); only agents that hold beliefs of
    their own (not the self agent, not nested holders) are named."""
    if not movers:
        return None

    def acts(agent: str) -> bool:
        return agents.get(agent) is False and ">" not in agent

    moved = {obj: agent for obj, agent in movers.items() if acts(agent)}

    def actor_of(fact: Fact) -> str | None:
        if fact.property == "IsInHand":
            return fact.target_id if acts(fact.target_id) else None
        if fact.property_type == "position":
            return moved.get(fact.subject_id)
        return None

    return actor_of
