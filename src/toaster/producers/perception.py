"""pdg facts: isPresent for perceived agents and IsInHand for held objects."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.producers.config import make_config, ns
from toaster.world.state import ROBOT, World


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
        out.add("isPresent", agents, "", conf=cfg["confidence_present"],
                obs=cfg["observability_present"])
        held = np.flatnonzero(live & (world.held_by[:n] >= 0))
        if held.size:
            agent = world.owner[world.held_by[held]]
            out.add("IsInHand", held, agent, obs=cfg["observability_in_hand"],
                    property_type="position", sub_property="object", tgt_owner=agent)
        return out
