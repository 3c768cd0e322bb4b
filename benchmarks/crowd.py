"""A synthetic crowd walking like the shared ETH/UCY tracks, written as a toaster tracks CSV.

Pedestrians walk at 1.2 ± 0.2 m/s between random goals in a square sized for 0.1 person per
m² (ETH/UCY scenes hold about that), and a third of the arrivals stop for 2–8 s before the
next goal, as people waiting or chatting do in those recordings. ``noise`` adds Gaussian
tracker noise (metres) to every sample.

Run: .venv/bin/python benchmarks/crowd.py OUT.csv --people 400 --hz 2.5 --seconds 120
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np


def write_crowd(path: Path, people: int, hz: float, seconds: float, noise: float = 0.0,
                seed: int = 0) -> int:
    """Write the crowd to ``path``; return the number of samples."""
    rng = np.random.default_rng(seed)
    side = math.sqrt(people / 0.1)
    pos = rng.uniform(0, side, (people, 2))
    goal = rng.uniform(0, side, (people, 2))
    speed = np.clip(rng.normal(1.2, 0.2, people), 0.5, 1.8)
    wait = np.zeros(people)
    yaw = np.zeros(people)
    dt = 1.0 / hz
    steps = int(seconds * hz) + 1
    ids = np.array([f"p{i}" for i in range(people)], dtype=object)
    with path.open("w") as out:
        out.write("t_s,id,kind,x,y,z,yaw\n")
        for step in range(steps):
            t = step * dt
            seen = pos + (rng.normal(0, noise, pos.shape) if noise else 0.0)
            lines = [f"{t:.4f},{i},human,{x:.4f},{y:.4f},0,{a:.4f}\n"
                     for i, (x, y), a in zip(ids, seen.tolist(), yaw.tolist(), strict=True)]
            out.writelines(lines)
            delta = goal - pos
            dist = np.linalg.norm(delta, axis=1)
            walking = wait <= 0
            move = np.minimum(speed * dt, dist)
            with np.errstate(invalid="ignore", divide="ignore"):
                unit = np.where(dist[:, None] > 0, delta / dist[:, None], 0.0)
            pos += np.where(walking[:, None], unit * move[:, None], 0.0)
            yaw = np.where(walking & (dist > 0), np.arctan2(delta[:, 1], delta[:, 0]), yaw)
            wait -= dt
            arrived = walking & (dist <= speed * dt)
            n = int(arrived.sum())
            if n:
                goal[arrived] = rng.uniform(0, side, (n, 2))
                wait[arrived] = np.where(rng.random(n) < 1 / 3, rng.uniform(2, 8, n), 0.0)
    return steps * people


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--people", type=int, default=400)
    parser.add_argument("--hz", type=float, default=2.5)
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--noise", type=float, default=0.0)
    args = parser.parse_args()
    print(write_crowd(args.out, args.people, args.hz, args.seconds, args.noise), "samples")


if __name__ == "__main__":
    main()
