"""agent_monitor: attention, motion, Distance and pointing for monitored agents, vectorised.

Every computation is a (monitored agents × entities) or (monitored joints × entities) array
operation; Python only builds the resulting Fact tuples. Differences from the original, all
deliberate (see docs/producers.md): angles are wrapped to (-pi, pi]; the head joint is found by
name for every agent (no hard-coded ids), also for looked-at agents; the body Δdistance
threshold is 0.12 m/s × the window (not ~0); the joint Δdistance sign is fixed (fires when the
joint approaches); IsMovingToward/distance confidence is the share of the motion spent
approaching (0..1); Distance "out" is not emitted unless ``distance_emit_out``; a held object
is no target of its holder's motion. docs/original.md lists every difference with its test.

Relevance (:mod:`toaster.producers.relevance`): pair facts are computed only for pairs within
range, found with a KD-tree on the targets built once per tick: IsMovingToward within
``toward_range`` (2D; toward a person within ``toward_range_humans``, unless the mover is
monitored by its id), Distance within ``dist_far``, IsLookingToward / IsLookingAt within
``look_toward_distance``. Debounce (:mod:`toaster.producers.debounce`): IsMoving of bodies and
joints is reported after ``min_duration["IsMoving"]`` of consistent evidence; the reported
state (not the raw one) selects the movers (IsMovingToward) and the still agents (joints).
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from typing import Any

import numpy as np

from toaster.errors import InvalidInputError
from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.producers.debounce import Debouncer, PairDebouncer
from toaster.producers.relevance import PlanarIndex, pair_distance, pairs_within
from toaster.timeutil import NS_PER_S
from toaster.world.config import make_config, ns
from toaster.world.geometry import bearing, gaze_axis, wrap_angle
from toaster.world.history import NO_TIME
from toaster.world.state import HUMAN, JOINT, ROBOT, World

_PAIR = 1 << 21  # pair key = mover row × _PAIR + target row (rows < 2M)
_CLASSES = {
    "humans": (HUMAN,),
    "robots": (ROBOT,),
    "agents": (HUMAN, ROBOT),
    "human": (HUMAN,),
    "robot": (ROBOT,),
    "agent": (HUMAN, ROBOT),
}
DIST_LABELS = np.array(["reach", "close", "medium", "far", "out"], dtype=object)


def _speed(
    world: World, rows: np.ndarray, window_ns: int, gap_ns: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(2D speed m/s, reference xy, elapsed s) over a window, per row; speed 0 if no sample."""
    elapsed, ref_pos, _ = world.history.window_sample(rows, window_ns, gap_ns)
    secs = elapsed / NS_PER_S
    step = np.linalg.norm(world.pos[rows, :2] - ref_pos[:, :2], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(secs > 0, step / secs, 0.0)
    return speed, ref_pos[:, :2], secs


class AgentMonitor:
    """Computes IsLookingToward / IsLookingAt / IsMoving / IsMovingToward / Distance."""

    name = "agent_monitor"

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = make_config(config)
        self._names_cache: tuple[int, np.ndarray] = (-1, np.zeros(0, object))
        moving_ns = ns(self.config, "min_duration", "IsMoving")
        self._body_moving = Debouncer(moving_ns)
        self._joint_moving = Debouncer(moving_ns)
        toward_ns = ns(self.config, "min_duration", "IsMovingToward")
        self._toward_state = {
            (part, sub): PairDebouncer(toward_ns)
            for part in ("body", "joint")
            for sub in ("direction", "distance")
        }
        # per part ("body", "joint"), the movers of this and of the last computed tick
        self._movers: dict[str, np.ndarray] = {}
        self._last_movers: dict[str, np.ndarray] = {}
        self._world: weakref.ref[World] | None = None

    # -- selection --------------------------------------------------------------------------
    def monitored_agents(self, world: World, live: np.ndarray) -> np.ndarray:
        """Rows of the live monitored agents (default: all humans).

        ``monitored_agents`` is a class (humans, robots, agents) or a list of classes and ids;
        ``-ID`` in the list excludes an agent a class brought in. Unknown ids are skipped (an
        agent may be monitored before it is first seen).
        """
        which = self.config["monitored_agents"]
        kind = world.kind[: world.n]
        items = [which] if isinstance(which, str) else list(which)
        table = np.zeros(4, bool)
        mask = np.zeros(world.n, bool)
        for item in items:
            kinds = _CLASSES.get(item)
            if kinds is not None:
                table[list(kinds)] = True
            elif isinstance(which, str):
                msg = (
                    f"monitored_agents {which!r} is not understood: use humans, robots, "
                    "agents or a list of agent ids"
                )
                raise InvalidInputError(msg)
            elif not str(item).startswith("-") and item in world.index:
                mask[world.index[item]] = True
        mask |= table[kind]
        for item in items:
            if str(item).startswith("-") and item[1:] in world.index:
                mask[world.index[item[1:]]] = False
        mask &= (kind == HUMAN) | (kind == ROBOT)
        return np.flatnonzero(mask & live)

    def named_agents(self, world: World) -> np.ndarray:
        """Per row, whether ``monitored_agents`` names it by its id (not through a class)."""
        which = self.config["monitored_agents"]
        mask = np.zeros(world.n, bool)
        if not isinstance(which, str):
            named = [i for i in which if i not in _CLASSES and not str(i).startswith("-")]
            mask[world.rows_of(named)] = True
        return mask

    def _joint_names(self, world: World) -> np.ndarray:
        if self._names_cache[0] != world.n:
            self._names_cache = (world.n, np.asarray(world.joint_names, dtype=object))
        return self._names_cache[1]

    def monitored_joints(self, world: World, agents: np.ndarray, live: np.ndarray) -> np.ndarray:
        """Rows of the monitored joints of the given agents (default: all their joints)."""
        n = world.n
        joints = np.flatnonzero((world.kind[:n] == JOINT) & live)
        mask = np.zeros(n, bool)
        mask[agents] = True
        joints = joints[mask[world.owner[joints]]]
        which = self.config["monitored_joints"]
        if which is None:
            return joints
        names = self._joint_names(world)
        if isinstance(which, Mapping):
            rows = [r for r in joints if names[r] in which.get(world.ids[world.owner[r]], ())]
            return np.asarray(rows, dtype=np.int64)
        return joints[np.isin(names[joints], list(which))]

    def head_rows(self, world: World) -> np.ndarray:
        """For every row, the row of its head joint (by name), or -1."""
        n = world.n
        names = self._joint_names(world)
        joints = np.flatnonzero(world.kind[:n] == JOINT)
        heads = joints[names[joints] == self.config["head_joint"]]
        head_of = np.full(n, -1, np.int64)
        head_of[world.owner[heads]] = heads
        return head_of

    # -- compute ----------------------------------------------------------------------------
    def compute(self, world: World, t_ns: int) -> list[Fact]:
        """All monitor facts for this tick."""
        return self.compute_batch(world, t_ns).facts()

    def compute_batch(self, world: World, t_ns: int) -> FactBatch:
        """All monitor facts for this tick, as arrays (see :mod:`toaster.producers.batch`)."""
        cfg = self.config
        n = world.n
        out = FactBatch(world)
        live = world.live_mask(t_ns, ns(cfg, "presence_timeout"))
        self._last_movers, self._movers = self._movers, {}
        agents = self.monitored_agents(world, live)
        if agents.size == 0:
            return out
        if self._world is None or self._world() is not world:
            self._world = weakref.ref(world)
            self._body_moving.reset()
            self._joint_moving.reset()
            for debouncer in self._toward_state.values():
                debouncer.reset()
            self._last_movers.clear()
        clock = world.t_ns[:n]
        targets = np.flatnonzero(live & (world.kind[:n] != JOINT))
        index = PlanarIndex(world.pos[targets, :2])  # KD-tree built on first need, this tick
        self._looking(world, agents, targets, index, out)
        gap = ns(cfg, "motion_max_gap")
        speed, _, _ = _speed(world, agents, ns(cfg, "body_speed_window"), gap)
        moving = self._body_moving.update(agents, speed > cfg["body_speed_threshold"], clock)
        obs = cfg["observability_monitor"]
        mov = agents[moving]
        if mov.size:
            s = speed[moving]
            out.add(
                "IsMoving",
                mov,
                value_num=s,
                conf=np.minimum(1.0, s * 3.6 / 5.0),
                obs=obs,
                property_type="motion",
                sub_property="agent",
            )
            self._toward(world, mov, targets, index, "body", out)
        still = agents[~moving]
        joints = self.monitored_joints(world, still, live)
        if joints.size:
            self._distance(world, joints, targets, index, out)
            jspeed, _, _ = _speed(world, joints, ns(cfg, "joint_speed_window"), gap)
        else:
            jspeed = np.zeros(0)
        # joints of moving (or absent) agents count as not moving for the debounce
        jm = self._joint_moving.update(joints, jspeed > cfg["joint_speed_threshold"], clock)
        jmov = joints[jm]
        if jmov.size:
            s = jspeed[jm]
            out.add(
                "IsMoving",
                jmov,
                value_num=s,
                conf=np.minimum(1.0, s * 3.6 / 20.0),
                obs=obs,
                property_type="motion",
                sub_property="joint",
            )
            self._toward(world, jmov, targets, index, "joint", out)
        return out

    def _looking(
        self,
        world: World,
        agents: np.ndarray,
        targets: np.ndarray,
        index: PlanarIndex,
        out: FactBatch,
    ) -> None:
        cfg = self.config
        head_of = self.head_rows(world)
        heads = head_of[agents]
        has = heads >= 0
        agents, heads = agents[has], heads[has]
        if agents.size == 0 or targets.size == 0:
            return
        reach, aperture = cfg["look_toward_distance"], cfg["look_toward_aperture"]
        target_head = head_of[targets]
        points = world.pos[np.where(target_head >= 0, target_head, targets)]
        hp = world.pos[heads]
        # the index holds the targets' bodies: widen the query by the farthest head offset
        headed = np.flatnonzero(target_head >= 0)
        offset = float(
            np.sqrt(((points[headed, :2] - index.xy[headed]) ** 2).sum(1)).max(initial=0.0)
        )
        ai, ti = index.candidates(hp, reach + offset)
        dist = pair_distance(hp, points, ai, ti)  # = norm over (dx, dy, dz), same rounding
        near = (dist <= reach) & (targets[ti] != agents[ai]) & (dist > 0)
        ai, ti, d = ai[near], ti[near], dist[near]
        if ai.size == 0:
            return
        axis = gaze_axis(world.rpy[heads])[ai]  # one rotation per head, not per pair
        delta = points[ti] - hp[ai]
        cos = np.einsum("ij,ij->i", delta, axis) / d
        ang = np.arccos(np.clip(cos, -1.0, 1.0))
        toward = ang < aperture / 2
        at = toward & (d <= reach / 2) & (ang < aperture / 8)
        obs = cfg["observability_monitor"]
        a_rows, t_rows = agents[ai], targets[ti]
        quarter = aperture / 4
        for keep, prop, width in (
            (toward, "IsLookingToward", aperture),
            (at, "IsLookingAt", quarter),
        ):
            a = ang[keep]
            out.add(
                prop,
                a_rows[keep],
                t_rows[keep],
                value_num=a,
                conf=(width - a) / width,
                obs=obs,
                property_type="attention",
                sub_property="agent",
            )

    def _toward(
        self,
        world: World,
        movers: np.ndarray,
        targets: np.ndarray,
        index: PlanarIndex,
        part: str,
        out: FactBatch,
    ) -> None:
        """IsMovingToward by direction and by distance for moving bodies or joints.

        Only targets nearer than ``toward_range`` (2D, from the mover's position) count, and
        never what the mover's agent holds (it moves with the hand: issue 27 item 4).
        """
        cfg = self.config
        gap = ns(cfg, "motion_max_gap")
        now = world.pos[movers, :2]
        tgt = index.xy
        rng = cfg["toward_range"]
        mi, ti = index.candidates(now, rng)
        dx = tgt[ti, 0] - now[mi, 0]
        dy = tgt[ti, 1] - now[mi, 1]
        after = np.sqrt(dx * dx + dy * dy)
        owner = world.owner[movers]
        body = np.where(owner >= 0, owner, movers)
        t_rows = targets[ti]
        # toward a person: within toward_range_humans, unless the mover's agent is monitored
        # by its id (add_agent), as the original computes it for the agents it monitors
        named = self.named_agents(world)[body[mi]]
        people = (world.kind[t_rows] == HUMAN) & ~named
        reach = np.where(people, cfg["toward_range_humans"], rng)
        # what the mover's agent holds moves with it: never a target of its own motion
        hand = world.held_by[t_rows]
        holder = np.where(hand >= 0, world.owner[np.maximum(hand, 0)], -1)
        keep = (after < reach) & (t_rows != body[mi]) & (t_rows != movers[mi])
        keep &= holder != body[mi]
        mi, ti, dx, dy, after = mi[keep], ti[keep], dx[keep], dy[keep], after[keep]
        _, ref_dir, _ = _speed(world, movers, ns(cfg, f"{part}_direction_window"), gap)
        heading = bearing(ref_dir, now)
        theta = cfg[f"{part}_toward_angle"]
        obs = cfg["observability_monitor"]
        dev = np.asarray(wrap_angle(heading[mi] - np.arctan2(dy, dx)))
        conf = (theta - np.abs(dev)) / theta
        pairs = movers[mi] * _PAIR + targets[ti]
        clock = world.t_ns[movers[mi]]
        # a continuing mover's new pair was absent at its previous sample: debounce its birth
        found, prev, _, _ = world.history.latest_at_or_before(movers, world.t_ns[movers] - 1)
        continuing = found & np.isin(movers, self._last_movers.get(part, ()))
        self._movers[part] = movers
        before = np.where(continuing, prev, NO_TIME)[mi]
        ok = self._toward_state[(part, "direction")].update(pairs, conf > 0, clock, before)
        held = np.maximum(conf[ok], 0.0)
        out.add(
            "IsMovingToward",
            movers[mi[ok]],
            targets[ti[ok]],
            value_num=held,  # the original's: the confidence (docs/original.md)
            conf=held,
            obs=obs,
            property_type="motion",
            sub_property="direction",
        )
        _, ref, secs = _speed(world, movers, ns(cfg, f"{part}_toward_distance_window"), gap)
        bx = ref[mi, 0] - tgt[ti, 0]
        by = ref[mi, 1] - tgt[ti, 1]
        delta = np.sqrt(bx * bx + by * by) - after
        step = np.linalg.norm(now - ref, axis=1)
        limit = cfg[f"{part}_toward_speed_threshold"] * secs
        raw = (delta > limit[mi]) & (step[mi] > 0)
        ok = self._toward_state[(part, "distance")].update(pairs, raw, clock, before)
        mi, ti, delta = mi[ok], ti[ok], delta[ok]
        with np.errstate(divide="ignore", invalid="ignore"):
            share = np.where(step[mi] > 0, delta / step[mi], 0.0)
        out.add(
            "IsMovingToward",
            movers[mi],
            targets[ti],
            value_num=delta,
            conf=np.clip(share, 0.0, 1.0),
            obs=obs,
            property_type="motion",
            sub_property="distance",
        )

    def _distance(
        self,
        world: World,
        joints: np.ndarray,
        targets: np.ndarray,
        index: PlanarIndex,
        out: FactBatch,
    ) -> None:
        cfg = self.config
        bounds = np.array(
            [cfg["dist_reach"], cfg["dist_close"], cfg["dist_medium"], cfg["dist_far"]]
        )
        jp, tp = world.pos[joints], world.pos[targets]
        if cfg["distance_emit_out"]:
            ji = np.repeat(np.arange(len(joints)), len(targets))
            ti = np.tile(np.arange(len(targets)), len(joints))
            d = pair_distance(jp, tp, ji, ti)
        else:
            # label < 4 (searchsorted right): strictly nearer than dist_far
            ji, ti, d = pairs_within(jp, tp, bounds[3], strict=True, index=index)
        label = np.searchsorted(bounds, d, side="right")
        out.add(
            "Distance",
            joints[ji],
            targets[ti],
            value_text=(label, DIST_LABELS),
            value_num=d,
            conf=cfg["confidence_distance"],
            obs=cfg["observability_monitor"],
            property_type="position",
            sub_property="3D",
        )


def pointing(
    world: World,
    agent_id: str,
    joint: str = "rightHand",
    *,
    t_ns: int | None = None,
    config: Mapping[str, Any] | None = None,
) -> list[tuple[str, float]]:
    """Entities an agent points at with a joint, best first, as (id, confidence).

    With ``t_ns``, poses come from the history as of that time (the "give me that" use case;
    the history spans about 3.3 s). The agent points when its joint is farther than
    ``pointing_joint_distance`` from its body (2D); the direction is body → joint (the
    original's quadrant bug fixed) and confidence = (θ − |wrap(dir − bearing(joint→e))|)/θ.
    """
    cfg = make_config(config)
    agent = world.row(agent_id)
    jrow = world.joint_of(agent_id, joint)
    if jrow < 0:
        msg = f"agent {agent_id!r} has no joint {joint!r}: give one of its joint names"
        raise InvalidInputError(msg)
    n = world.n
    rows = np.flatnonzero(world.active[:n] & (world.kind[:n] != JOINT))
    rows = rows[rows != agent]
    if t_ns is None:
        pos = world.pos[:n]
        found = np.ones(n, bool)
    else:
        found, pos, _ = world.history.as_of(np.arange(n), t_ns)
    body, hand = pos[agent, :2], pos[jrow, :2]
    if np.linalg.norm(hand - body) <= cfg["pointing_joint_distance"]:
        return []
    rows = rows[found[rows]]
    direction = bearing(body, hand)
    dev = wrap_angle(direction - bearing(hand[None, :], pos[rows, :2]))
    theta = cfg["pointing_angle"]
    conf = (theta - np.abs(dev)) / theta
    keep = conf > 0
    pairs = sorted(zip(conf[keep].tolist(), rows[keep].tolist(), strict=True), reverse=True)
    return [(world.ids[r], c) for c, r in pairs]
