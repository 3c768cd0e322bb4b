"""Synthetic crowds walking like the shared ETH/UCY tracks, written as toaster tracks CSV.

Pedestrians walk at 1.2 ± 0.2 m/s (the recordings' typical speed) and a third of them stop
once for 2–8 s, as people waiting or chatting do there. Two layouts:

* ``arrivals`` > 0 (like the recordings): people enter the square scene at a random point of
  its edge, one every 1/arrivals seconds on average, walk to a random point of another edge and
  leave; the scene's side is sized so that about 0.12 person per m² are in it at once (the
  busiest ETH/UCY scenes). ``people`` is the number of distinct ids of the whole recording.
* ``arrivals`` = 0 (a stress test): every person is in the scene from the start and walks
  between random goals in a square of 0.1 person per m².

``noise`` adds Gaussian tracker noise (metres) to every sample.

Run: .venv/bin/python benchmarks/crowd.py OUT.csv --people 400 --hz 2.5 --seconds 200
     [--arrivals 2] [--noise 0.02]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

SPEED, DENSITY = 1.2, 0.12


def _edge_points(rng: np.random.Generator, n: int, side: float) -> tuple[np.ndarray, np.ndarray]:
    """``n`` (entry, exit) pairs on different edges of the square."""
    edge = rng.integers(0, 4, n)
    other = (edge + rng.integers(1, 4, n)) % 4

    def on(e: np.ndarray) -> np.ndarray:
        u = rng.uniform(0, side, len(e))
        x = np.select([e == 0, e == 1, e == 2], [u, np.full(len(e), side), u], 0.0)
        y = np.select([e == 0, e == 1, e == 2], [np.zeros(len(e)), u, np.full(len(e), side)], u)
        return np.column_stack([x, y])

    return on(edge), on(other)


def write_crowd(
    path: Path,
    people: int,
    hz: float,
    seconds: float,
    noise: float = 0.0,
    seed: int = 0,
    arrivals: float = 0.0,
) -> int:
    """Write the crowd to ``path``; return the number of samples."""
    rng = np.random.default_rng(seed)
    if arrivals > 0:
        # people in the scene ≈ arrivals × (side / speed + stops) = DENSITY × side²
        stops = 5.0 / 3
        side = (
            arrivals / SPEED + math.sqrt((arrivals / SPEED) ** 2 + 4 * DENSITY * arrivals * stops)
        ) / (2 * DENSITY)
        start = np.sort(rng.uniform(0, people / arrivals, people))
        pos, goal = _edge_points(rng, people, side)
    else:
        side = math.sqrt(people / 0.1)
        start = np.zeros(people)
        pos, goal = rng.uniform(0, side, (people, 2)), rng.uniform(0, side, (people, 2))
    speed = np.clip(rng.normal(SPEED, 0.2, people), 0.5, 1.8)
    stop_at = np.where(rng.random(people) < 1 / 3, rng.uniform(0.2, 0.8, people), 2.0)
    stop_for = rng.uniform(2, 8, people)
    walked = np.zeros(people)
    total = np.linalg.norm(goal - pos, axis=1)
    wait = np.zeros(people)
    gone = np.zeros(people, bool)
    yaw = np.arctan2(*(goal - pos).T[::-1])
    dt = 1.0 / hz
    steps = int(seconds * hz) + 1
    ids = np.array([f"p{i}" for i in range(people)], dtype=object)
    samples = 0
    with path.open("w") as out:
        out.write("t_s,id,kind,x,y,z,yaw\n")
        for step in range(steps):
            t = step * dt
            here = (start <= t) & ~gone
            seen = pos + (rng.normal(0, noise, pos.shape) if noise else 0.0)
            rows = np.flatnonzero(here)
            out.writelines(
                f"{t:.4f},{ids[i]},human,{x:.4f},{y:.4f},0,{a:.4f}\n"
                for i, (x, y), a in zip(
                    rows.tolist(), seen[rows].tolist(), yaw[rows].tolist(), strict=True
                )
            )
            samples += len(rows)
            delta = goal - pos
            dist = np.linalg.norm(delta, axis=1)
            walking = here & (wait <= 0)
            move = np.minimum(speed * dt, dist)
            with np.errstate(invalid="ignore", divide="ignore"):
                unit = np.where(dist[:, None] > 0, delta / dist[:, None], 0.0)
            pos += np.where(walking[:, None], unit * move[:, None], 0.0)
            walked += np.where(walking, move, 0.0)
            yaw = np.where(walking & (dist > 0), np.arctan2(delta[:, 1], delta[:, 0]), yaw)
            wait -= np.where(here, dt, 0.0)
            pause = walking & (walked >= stop_at * total)
            wait[pause] = stop_for[pause]
            stop_at[pause] = 2.0  # once
            arrived = walking & (dist <= speed * dt)
            if arrivals > 0:
                gone |= arrived
            elif arrived.any():
                n = int(arrived.sum())
                goal[arrived] = rng.uniform(0, side, (n, 2))
                total[arrived] = np.linalg.norm(goal[arrived] - pos[arrived], axis=1)
                walked[arrived] = 0.0
    return samples


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--people", type=int, default=400)
    parser.add_argument("--hz", type=float, default=2.5)
    parser.add_argument("--seconds", type=float, default=200.0)
    parser.add_argument("--arrivals", type=float, default=2.0)
    parser.add_argument("--noise", type=float, default=0.0)
    args = parser.parse_args()
    print(
        write_crowd(
            args.out, args.people, args.hz, args.seconds, args.noise, arrivals=args.arrivals
        ),
        "samples",
    )


if __name__ == "__main__":
    main()
