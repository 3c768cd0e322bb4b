"""IsMoving / IsMovingToward on ETH hotel and UCY zara01 tracks against their annotations."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from toaster.model import Fact
from toaster.producers import AgentMonitor
from toaster.world import World, read_obsmat

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "eth-ucy-opentraj"
SCENES = {"hotel": DATA / "ETH" / "seq_hotel", "zara01": DATA / "UCY" / "zara01"}

pytestmark = [
    pytest.mark.shared_data,
    pytest.mark.slow,
    pytest.mark.skipif(not DATA.is_dir(), reason=f"shared data not found at {DATA}"),
]


def destinations(folder: Path) -> np.ndarray:
    pts = np.loadtxt(folder / "destinations.txt", ndmin=2)
    return pts[np.all(np.abs(pts) <= 100, axis=1)]


def replay(folder: Path) -> dict:
    """Tick at every annotated frame; collect IsMoving and the destinations moved toward.

    A track's first sample is left out of the agreement (there is no motion to see yet).
    """
    raw = np.loadtxt(folder / "obsmat.txt", ndmin=2)
    src = read_obsmat(folder / "obsmat.txt")
    world = World()
    src.setup(world)
    dests = destinations(folder)
    for k, (x, y) in enumerate(dests):
        world.add_entity(f"dest{k}", "object")
        world.set_pose(f"dest{k}", (x, y, 0), int(src.t[0]))
    # walkers only look at destinations: the direction fact is computed against every entity
    monitor = AgentMonitor()
    moving: dict[tuple[int, str], bool] = {}
    best: dict[tuple[int, str], str] = {}
    among: dict[tuple[int, str], set[str]] = {}
    for t in np.unique(src.t).tolist():
        src.advance(world, t)
        world.commit()
        facts: list[Fact] = monitor.compute(world, t)
        seen_now = {world.ids[r] for r in np.flatnonzero(world.t_ns[: world.n] == t)}
        for eid in seen_now:
            moving[(t, eid)] = False
        scores: dict[str, tuple[float, str]] = {}
        for f in facts:
            if f.property == "IsMoving" and f.subject_id in seen_now:
                moving[(t, f.subject_id)] = True
            elif (
                f.property == "IsMovingToward"
                and f.sub_property == "direction"
                and f.target_id.startswith("dest")
                and f.subject_id in seen_now
            ):
                among.setdefault((t, f.subject_id), set()).add(f.target_id)
                scores[f.subject_id] = max(
                    scores.get(f.subject_id, (0.0, "")), (f.confidence, f.target_id)
                )
        for eid, (_, dest) in scores.items():
            best[(t, eid)] = dest
    t_of = (raw[:, 0].astype(np.int64) * 40_000_000).tolist()
    ped = [f"ped{int(p)}" for p in raw[:, 1]]
    annotated = np.hypot(raw[:, 5], raw[:, 7]) > 0.12
    computed = np.array([moving[(t, p)] for t, p in zip(t_of, ped, strict=True)])
    order = np.lexsort((raw[:, 0], raw[:, 1]))
    first = np.zeros(len(raw), bool)
    first[order[np.r_[True, raw[order[1:], 1] != raw[order[:-1], 1]]]] = True
    # the walker's destination: the one nearest to where its track ends
    last = {}
    for p, x, y in zip(ped, raw[:, 2], raw[:, 4], strict=True):
        last[p] = (x, y)
    goal = {p: f"dest{int(np.argmin(np.hypot(*(dests - xy).T)))}" for p, xy in last.items()}
    hits = [best[(t, p)] == goal[p] for t, p in zip(t_of, ped, strict=True) if (t, p) in best]
    # only destinations within IsMovingToward's range can be targets (relevance)
    reach = monitor.config["toward_range"]
    dest_xy = {f"dest{k}": xy for k, xy in enumerate(dests)}
    moving_keys = [
        (t, p)
        for t, p, x, y in zip(t_of, ped, raw[:, 2], raw[:, 4], strict=True)
        if moving[(t, p)] and np.hypot(*(dest_xy[goal[p]] - (x, y))) < reach
    ]
    inside = [goal[p] in among.get((t, p), ()) for t, p in moving_keys]
    return {
        "agreement": float(np.mean((computed == annotated)[~first])),
        "agreement_all": float(np.mean(computed == annotated)),
        "samples": int((~first).sum()),
        "among": float(np.mean(inside)),
        "moving": len(moving_keys),
        "toward_samples": len(hits),
        "toward_hits": float(np.mean(hits)) if hits else 0.0,
    }


@pytest.mark.parametrize("scene", ["hotel", "zara01"])
def test_is_moving_agrees_with_annotated_velocity(scene):
    result = replay(SCENES[scene])
    print(
        f"\n{scene}: IsMoving agreement {result['agreement']:.2%} on {result['samples']} "
        f"samples with a previous sample ({result['agreement_all']:.2%} counting each track's "
        f"first sample, which has no motion yet); final destination among "
        f"IsMovingToward(direction) targets on {result['among']:.1%} of {result['moving']} "
        f"moving samples whose destination is in range, the most confident on {result['toward_hits']:.1%}"
    )
    assert result["agreement"] >= 0.97
    assert result["among"] > 0.3  # a report more than an oracle: see docs/producers.md
