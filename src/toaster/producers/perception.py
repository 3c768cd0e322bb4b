"""pdg facts: isPresent for perceived agents and IsInHand for held objects."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from toaster.model import Fact
from toaster.producers.config import make_config, ns
from toaster.world.state import ROBOT, World


class PerceptionFacts:
    """isPresent (humans and robots perceived within ``presence_timeout``) and IsInHand."""

    name = "pdg"

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = make_config(config)

    def compute(self, world: World, t_ns: int) -> list[Fact]:
        """Facts for this tick."""
        cfg, n, ids = self.config, world.n, world.ids
        live = world.live_mask(t_ns, ns(cfg, "presence_timeout"))
        agents = np.flatnonzero(live & (world.kind[:n] <= ROBOT))
        facts = [Fact(ids[a], "isPresent", "", "true", None, cfg["confidence_present"],
                      cfg["observability_present"]) for a in agents.tolist()]
        held = np.flatnonzero(live & (world.held_by[:n] >= 0))
        for obj in held.tolist():
            agent = ids[world.owner[world.held_by[obj]]]
            facts.append(Fact(ids[obj], "IsInHand", agent, "true", None, 1.0,
                              cfg["observability_in_hand"], "position", "object", "", agent))
        return facts
