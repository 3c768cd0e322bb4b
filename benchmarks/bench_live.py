"""Latency of a live toaster: from a pose published by another process to (a) the fact in the
database (seen by a `toaster.queries.watch` reader in a third connection) and (b) the
`toaster_msgs/FactList` received by an external ROS subscriber.

The path users run: a real roscore, `toaster serve --ros1 --tf-map FRAMES` (30 Hz), and a rospy
client under Debian's Python (`live_client.py`) that publishes /tf for H humans (2 joints each)
and 50 objects at 30 Hz, moving each human into and out of a zone once a second. Baseline in
the same run: the same scene pushed in-process into a `LiveNode` (no ROS transport), database
latency only. Quoted: medians over repeats of p50 / p99 in ms, ticks and overruns, and how long
input waited for its tick (p50 / p99 of the node's waits: from the first pose that woke its loop
to the start of the tick that applies it; `toaster serve` reports them in its status lines).

Run: .venv/bin/python benchmarks/bench_live.py [--no-pg | --only-pg] [--seconds 20] [--repeats 3]
     [--humans 10,100] [--quick]
(``--quick``: 3 humans, 2 s, one run per path: a smoke run.)
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np

import toaster
from bench_run import Database
from live_scene import human_pose, joint_offsets, object_pose, zone
from toaster.node import LiveNode
from toaster.queries import watch
from toaster.ros1.core import RosCore

HERE = Path(__file__).resolve().parent
PG_DEFAULT = "postgresql://postgres@127.0.0.1:5432/test"
LISTENER = [sys.executable, str(HERE / "foxglove_listener.py")]


def put_zones(url: str, humans: int) -> None:
    """Each human's zone, stored before the node starts."""
    with toaster.connect(url) as db:
        store = db.store()
        for i in range(humans):
            store.put_area(f"zone_h{i}", zone(i))


def frame_map(humans: int, objects: int) -> dict[str, Any]:
    frames: dict[str, Any] = {}
    for i in range(humans):
        frames[f"h{i}_base"] = {"id": f"h{i}", "kind": "human"}
        for joint in joint_offsets():
            frames[f"h{i}_{joint}"] = {"kind": "joint", "owner": f"h{i}", "joint": joint}
    for j in range(objects):
        frames[f"o{j}"] = {"id": f"o{j}", "kind": "object"}
    return frames


class Watcher:
    """Arrival wall times of each human's IsInArea zone_<human> changes, read by a third
    connection."""

    def __init__(self, url: str) -> None:
        self.seen: list[tuple[str, bool, int]] = []
        self.stop = threading.Event()
        self.db = toaster.connect(url)
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        for row in watch(
            self.db, property="IsInArea", target="zone_*", poll_s=0.002, stop=self.stop
        ):
            if row.target_id == f"zone_{row.subject_id}":
                self.seen.append((row.subject_id, row.kind == "appeared", time.time_ns()))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(10)
        self.db.close()


def latencies(toggles: list, seen: list) -> list[float]:
    """ms from each toggle to the first matching arrival after it."""
    out = []
    for human, inside, sent in toggles:
        after = [t for h, i, t in seen if h == human and i == inside and t >= sent]
        if after:
            out.append((min(after) - sent) / 1e6)
    return out


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def ros_run(
    backend: str, pg: str, humans: int, seconds: float, tmp: str, foxglove: bool = False
) -> dict[str, Any]:
    """One run with roscore, `toaster serve --ros1` and the rospy client (``foxglove``: and
    `--foxglove 0` with foxglove_listener.py on /toaster/facts, the same ticks)."""
    database = Database(backend, pg, tmp)
    frames = Path(tmp) / f"frames{humans}.json"
    frames.write_text(json.dumps(frame_map(humans, 50)))
    try:
        put_zones(database.url, humans)
        with RosCore(Path(tmp) / f"ros-{uuid.uuid4().hex[:6]}") as env:
            log = Path(tmp) / "serve.log"
            with log.open("w") as err:
                node = subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "toaster",
                        "--db",
                        database.url,
                        "serve",
                        "--ros1",
                        "--tf-map",
                        str(frames),
                        "--status-every",
                        "2",
                        *(["--foxglove", "0"] if foxglove else []),
                    ],
                    env=env,
                    stderr=err,
                    start_new_session=True,
                )
                while "(Ctrl-C stops)" not in log.read_text():
                    if node.poll() is not None:
                        raise RuntimeError(log.read_text()[-2000:])
                    time.sleep(0.05)
                watcher = Watcher(database.url)
                listener = None
                if foxglove:
                    port = re.search(r"Foxglove on ws://127.0.0.1:(\d+)", log.read_text())
                    assert port is not None
                    listener = subprocess.Popen(
                        [*LISTENER, port[1], str(seconds + 300)],  # until SIGINT
                        stdout=subprocess.PIPE,
                        text=True,
                    )
                client = subprocess.run(
                    [
                        "/usr/bin/python3",
                        str(HERE / "live_client.py"),
                        str(humans),
                        "50",
                        str(seconds),
                    ],
                    env=env,
                    capture_output=True,
                    text=True,
                    timeout=seconds + 120,
                )
                watcher.close()
                fox_out = ""
                if listener is not None:
                    time.sleep(1.0)  # as the rospy client waits for its last fact lists
                    listener.send_signal(signal.SIGINT)
                    fox_out = listener.communicate(timeout=60)[0]
                os.killpg(node.pid, signal.SIGTERM)
                node.wait(30)
            if client.returncode != 0:
                raise RuntimeError(client.stderr[-2000:])
            out = json.loads(client.stdout.strip().splitlines()[-1])
            summary = log.read_text()
    finally:
        database.close()
    found = re.search(
        r"stopped after (\d+) ticks \((\d+) overran [\d.]+ ms; median "
        r"([\d.]+) ms",
        summary,
    )
    ticks, overruns, median = found.groups() if found else ("nan", "nan", "nan")
    waits = re.findall(r"input waits p50 ([\d.]+) ms, p99 ([\d.]+) ms", summary)
    return {
        "wait": [float(w) for w in waits[-1]] if waits else [math.nan, math.nan],
        "db": latencies(out["toggles"], watcher.seen),
        "ros": latencies(out["toggles"], out["seen"]),
        "fox": latencies(out["toggles"], json.loads(fox_out)["seen"]) if fox_out else [],
        "toggles": len(out["toggles"]),
        "ticks": int(ticks),
        "overruns": int(overruns),
        "tick_ms": float(median),
    }


def api_run(backend: str, pg: str, humans: int, seconds: float, tmp: str) -> dict[str, Any]:
    """Baseline: the same scene pushed in-process (no ROS), database latency only."""
    database = Database(backend, pg, tmp)
    try:
        put_zones(database.url, humans)
        with toaster.connect(database.url) as db:
            node = LiveNode(db)
            stop = threading.Event()
            loop = threading.Thread(target=node.run, kwargs={"stop": stop})
            loop.start()
            watcher = Watcher(database.url)
            toggles, inside = [], [False] * humans
            start = time.monotonic()
            tick = 0
            while time.monotonic() - start < seconds:
                elapsed = time.monotonic() - start
                wall = time.time_ns()
                for i in range(humans):
                    want, x, y = human_pose(i, humans, elapsed)
                    if want != inside[i]:
                        inside[i] = want
                        toggles.append([f"h{i}", want, wall])
                    node.api.push(f"h{i}", (x, y, 0.0), t_ns=wall)
                    for joint, (dx, dy, dz) in joint_offsets().items():
                        node.api.push(
                            f"h{i}/{joint}",
                            (x + dx, y + dy, dz),
                            kind="joint",
                            owner_id=f"h{i}",
                            joint=joint,
                            t_ns=wall,
                        )
                for j in range(50):
                    node.api.push(f"o{j}", object_pose(j), kind="object", t_ns=wall)
                tick += 1
                time.sleep(max(0.0, start + tick / 30 - time.monotonic()))
            time.sleep(1.0)
            watcher.close()
            stop.set()
            loop.join()
            stats = node.stats
    finally:
        database.close()
    waits = getattr(stats, "wait_ms", None) or [math.nan]  # (older code: not measured)
    return {
        "wait": [pct(waits, 50), pct(waits, 99)],
        "db": latencies(toggles, watcher.seen),
        "ros": [],
        "fox": [],
        "toggles": len(toggles),
        "ticks": stats.ticks,
        "overruns": stats.overruns,
        "tick_ms": statistics.median(stats.tick_ms) if stats.tick_ms else float("nan"),
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--pg", default=os.environ.get("TOASTER_BENCH_PG", PG_DEFAULT))
    parser.add_argument("--no-pg", action="store_true", help="SQLite only")
    parser.add_argument("--only-pg", action="store_true", help="PostgreSQL only")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--humans", default="10,100")
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    parser.add_argument(
        "--foxglove",
        action="store_true",
        help="also `toaster serve --ros1 --foxglove`: FactList and /toaster/facts latency "
        "of the same ticks (needs toaster[foxglove] and websockets)",
    )
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.repeats, args.humans = 2.0, 1, "3"
    backends = ([] if args.only_pg else ["sqlite"]) + ([] if args.no_pg else ["postgresql"])
    print(
        f"Live latency, pose published -> fact (ms; median over {args.repeats} runs of each "
        f"run's p50 / p99; {args.seconds:.0f} s per run, 30 Hz, 50 objects, 2 joints per "
        "human; target p99 < 33 ms for 10 humans)"
    )
    print(
        f"{'path':<20} {'humans':>6} {'backend':<11} {'changes':>8} {'db p50':>7} "
        f"{'db p99':>7} {'ros p50':>8} {'ros p99':>8} {'tick ms':>8} {'overruns':>9}"
        f" {'wait p50':>9} {'wait p99':>9}" + (" fox p50  fox p99" if args.foxglove else "")
    )
    paths: list[tuple[str, Any]] = [
        ("in-process (base)", api_run),
        ("toaster serve --ros1", ros_run),
    ]
    if args.foxglove:
        paths.append(
            ("serve --ros1 --fox", functools.partial(ros_run, foxglove=True))  # same ticks
        )
    with tempfile.TemporaryDirectory() as tmp:
        for humans in (int(h) for h in args.humans.split(",")):
            for backend in backends:
                for label, run in paths:
                    runs = [
                        run(backend, args.pg, humans, args.seconds, tmp)
                        for _ in range(args.repeats)
                    ]

                    def med(key: str, q: float, runs: list = runs) -> float:
                        return statistics.median(pct(r[key], q) for r in runs)

                    print(
                        f"{label:<20} {humans:>6} {backend:<11} "
                        f"{statistics.median(r['toggles'] for r in runs):>8.0f} "
                        f"{med('db', 50):>7.1f} {med('db', 99):>7.1f} {med('ros', 50):>8.1f} "
                        f"{med('ros', 99):>8.1f} "
                        f"{statistics.median(r['tick_ms'] for r in runs):>8.1f} "
                        f"{statistics.median(r['overruns'] for r in runs):>9.0f}"
                        f" {statistics.median(r['wait'][0] for r in runs):>9.1f}"
                        f" {statistics.median(r['wait'][1] for r in runs):>9.1f}"
                        + (
                            f" {med('fox', 50):>8.1f} {med('fox', 99):>8.1f}"
                            if args.foxglove
                            else ""
                        ),
                        flush=True,
                    )


if __name__ == "__main__":
    main()
