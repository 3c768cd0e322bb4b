"""The original's three entity lists of an area: inside, upcoming and leaving.

With hysteresis (:mod:`toaster.producers.areas`), an entity between the inner and the nominal
boundary that is not inside is *upcoming* (it counts as out until it crosses the inner one);
an entity inside that is between the nominal and the outer boundary is *leaving* (it still
counts as in until it crosses the outer one). Without hysteresis both lists stay empty. Worked
out on request (print_area, the published area list), from the AreaManager's memberships and
each area's nominal shape: nothing is added to a tick.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from toaster.producers.areas import AreaManager, _compile, _Compiled, _inside
from toaster.world.config import ns
from toaster.world.geometry import to_local_xy
from toaster.world.state import World


class Lists(NamedTuple):
    """Entity ids of one area, each list sorted."""

    inside: list[str]
    upcoming: list[str]
    leaving: list[str]


class AreaLists:
    """Inside / upcoming / leaving lists of an AreaManager's areas (nominal shapes cached)."""

    def __init__(self, manager: AreaManager) -> None:
        self.manager = manager
        self._nominal: dict[str, tuple[dict[str, Any], _Compiled]] = {}

    def _shape(self, area_id: str, spec: dict[str, Any]) -> _Compiled:
        got = self._nominal.get(area_id)
        if got is None or got[0] is not spec:
            flat = {**spec, "enter_hysteresis": 0.0, "leave_hysteresis": 0.0}
            got = self._nominal[area_id] = (spec, _compile(area_id, flat))
        return got[1]

    def lists(self, world: World, t_ns: int) -> dict[str, Lists]:
        """Every area's lists as of the last tick (areas whose owner is away: all empty)."""
        manager = self.manager
        live = world.live_mask(t_ns, ns(manager.config, "presence_timeout"))
        out: dict[str, Lists] = {}
        for area_id, spec in manager.areas.items():
            inside = manager.inside(area_id, world)
            if not (spec["enter_hysteresis"] or spec["leave_hysteresis"]):
                out[area_id] = Lists(sorted(inside), [], [])
                continue
            area = self._shape(area_id, spec)
            rows = np.flatnonzero(live & area.kinds[world.kind[: world.n]])
            pos = world.pos[rows]
            xy, z_shift = pos[:, :2], 0.0
            if spec["owner"]:
                owner = world.index.get(spec["owner"], -1)
                if owner < 0 or not live[owner]:
                    out[area_id] = Lists([], [], [])
                    continue
                keep = (rows != owner) & (world.owner[rows] != owner)
                rows, pos = rows[keep], pos[keep]
                xy = to_local_xy(pos[:, :2], world.pos[owner, :2], world.rpy[owner, 2])
                z_shift = world.pos[owner, 2]
            in_band = (pos[:, 2] >= area.z_lo + z_shift) & (pos[:, 2] <= area.z_hi + z_shift)
            nominal = in_band & _inside(area.outer, xy)
            member = np.isin(rows, world.rows_of(inside))
            ids = world.ids
            out[area_id] = Lists(
                sorted(inside),
                sorted(ids[r] for r in rows[nominal & ~member].tolist()),
                sorted(ids[r] for r in rows[~nominal & member].tolist()),
            )
        return out
