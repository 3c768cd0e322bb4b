"""IsSeen (the original's pdg "affordance" fact, listed in its documentation, never emitted):
which entities the robot perceives now.

Two rules, one per kind of input (docs/producers.md, "IsSeen"):

* **Detected**: an input that lists what it detects (ROS4HRI's tracked bodies and faces)
  reports it with :meth:`SeenFacts.report`. An entity such a detector ever listed is seen
  exactly while the detector's newest list, no older than ``presence_timeout``, names it:
  ``<entity> IsSeen <observer>``, sub-property ``detected`` (the observer is the detector's
  robot, the node's self agent; empty when unknown).
* **Field of view** (simulated input: toaster_simu, set_entity_pose, scenarios, poses from
  /tf, which say where things are, not what the robot sees): every other live human, robot or
  object is seen by each live robot whose camera has it within ``view_range`` metres and
  half of ``view_aperture`` around the gaze: ``<entity> IsSeen <robot>``, sub-property
  ``view``. The camera is the robot's ``head_joint`` (its pose, pitch included) or else
  ``eye_height`` above the robot looking along its yaw; the point looked at is the middle of
  the entity's height (its size, else ``agent_size`` for agents, else its position).

No occlusion (move3d_facts' IsVisibleBy has it): one vectorised test per robot, O(robots ×
entities) a tick, cheap for crowds. Observability 0: a person does not perceive what the robot
perceives, so IsSeen stays the robot's own belief (nothing to propagate in a crowd).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple

import numpy as np

from toaster.producers.batch import FactBatch
from toaster.timeutil import now_ns
from toaster.world.config import make_config, ns
from toaster.world.geometry import gaze_axis
from toaster.world.state import HUMAN, JOINT, OBJECT, ROBOT, World

#: Reports a detector may hold at most ids in (a publisher cannot make it grow without end).
MAX_REPORTED = 100_000


class Report(NamedTuple):
    """A detector's newest list: what it detects, whose perception it is, when it came."""

    ids: frozenset[str]
    observer: str
    t_ns: int


class SeenFacts:
    """IsSeen from detectors' reports, and from the robots' field of view otherwise."""

    name = "pdg_seen"

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = make_config(config)
        self._reports: dict[str, Report] = {}
        self._lock = threading.Lock()
        self._detected = np.zeros(0, bool)  # rows a detector ever listed (they follow rule 1)

    def report(
        self, detector: str, ids: Iterable[str], observer: str = "", t_ns: int | None = None
    ) -> None:
        """``detector``'s current list of the entities it detects (any thread; replaces its
        previous list); ``t_ns`` defaults to now."""
        listed = frozenset(str(i) for i in list(ids)[:MAX_REPORTED])
        with self._lock:
            self._reports[detector] = Report(listed, observer, now_ns() if t_ns is None else t_ns)

    def compute(self, world: World, t_ns: int) -> list[Any]:
        """Facts for this tick."""
        return self.compute_batch(world, t_ns).facts()

    def compute_batch(self, world: World, t_ns: int) -> FactBatch:
        """Facts for this tick, as arrays."""
        n, cfg = world.n, self.config
        out = FactBatch(world)
        timeout = ns(cfg, "presence_timeout")
        live = world.live_mask(t_ns, timeout)
        if len(self._detected) < n:
            self._detected = np.concatenate(
                [self._detected, np.zeros(n - len(self._detected), bool)]
            )
        with self._lock:
            reports = list(self._reports.values())
        seen: dict[str, list[np.ndarray]] = {}  # observer -> rows its fresh lists name
        for report in reports:
            rows = world.rows_of(report.ids)
            rows = rows[world.kind[rows] != JOINT] if rows.size else rows
            self._detected[rows] = True
            if t_ns - report.t_ns <= timeout:  # a stale list: its detector sees nothing now
                seen.setdefault(report.observer, []).append(rows[live[rows]])
        for observer, parts in sorted(seen.items()):
            out.add(
                "IsSeen",
                np.unique(np.concatenate(parts)),
                observer,
                obs=0.0,
                property_type="affordance",
                sub_property="detected",
            )
        self._in_view(world, live, live & ~self._detected[:n], out)
        return out

    def _in_view(
        self, world: World, live: np.ndarray, candidates: np.ndarray, out: FactBatch
    ) -> None:
        """Rule 2: the live robots' field of view over the candidates."""
        n, cfg = world.n, self.config
        kind = world.kind[:n]
        robots = np.flatnonzero(live & (kind == ROBOT))
        cand = np.flatnonzero(candidates & ((kind == HUMAN) | (kind == ROBOT) | (kind == OBJECT)))
        if not robots.size or not cand.size:
            return
        height = world.size[cand, 2].copy()
        agent = kind[cand] <= ROBOT
        unknown = ~np.isfinite(height)
        height[unknown & agent] = cfg["agent_size"][2]
        height[unknown & ~agent] = 0.0
        points = world.pos[cand].copy()
        points[:, 2] += height / 2
        cos_half = math.cos(min(cfg["view_aperture"], 2 * math.pi) / 2)
        reach = cfg["view_range"]
        for robot in robots.tolist():
            head = world.joint_of(world.ids[robot], cfg["head_joint"])
            if head >= 0:
                eye, rpy = world.pos[head], world.rpy[head]
            else:
                eye = world.pos[robot] + (0.0, 0.0, cfg["eye_height"])
                rpy = np.array([0.0, 0.0, world.rpy[robot, 2]])
            d = points - eye
            dist = np.linalg.norm(d, axis=1)
            ahead = d @ gaze_axis(rpy)
            seen = cand[(dist <= reach) & (ahead >= cos_half * dist) & (cand != robot)]
            out.add(
                "IsSeen",
                seen,
                np.full(len(seen), robot, np.int64),
                obs=0.0,
                property_type="affordance",
                sub_property="view",
            )
