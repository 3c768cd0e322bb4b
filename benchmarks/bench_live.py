"""Latency of a live toaster: from a pose published by another process to (a) the fact in the
database (seen by a `toaster.queries.watch` reader in a third connection) and (b) the
`toaster_msgs/FactList` received by an external ROS subscriber.

The path users run: a real roscore, `toaster serve --ros1 --tf-map FRAMES` (30 Hz), and a rospy
client under Debian's Python (`live_client.py`) that publishes /tf for H humans (2 joints each)
and 50 objects at 30 Hz, moving each human into and out of a zone once a second. Baseline in
the same run: the same scene pushed in-process into a `LiveNode` (no ROS transport), database
latency only. ``--foxglove``: also `--ros1 --foxglove 0`, the FactList and Foxglove's
/toaster/facts (foxglove_listener.py) of the same ticks. ``--ros2``: also `toaster serve --ros2`
with the scene published over DDS (live_client_ros2.py: cyclonedds, rosbags, no ROS 2 install) on a
random ROS_DOMAIN_ID over loopback. The paths alternate within each repeat; after the table,
the ROS 2 FactList's and Foxglove's p50 / p99 as ratios to the `--ros1` FactList's (medians
over repeats of each repeat's ratio). Quoted: medians over repeats of p50 / p99 in ms, ticks and
overruns, and how long input waited for its tick (p50 / p99 of the node's waits: from the first
pose that woke its loop to the start of the tick that applies it; `toaster serve` reports them
in its status lines).

Run: .venv/bin/python benchmarks/bench_live.py [--no-pg | --only-pg] [--seconds 20] [--repeats 3]
     [--humans 10,100] [--foxglove] [--ros2] [--quick]
(``--quick``: 3 humans, 2 s, one run per path: a smoke run.)
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import random
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
#: cyclonedds on loopback only, unicast discovery (no multicast on a shared machine)
LOOPBACK = (
    '<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface address="127.0.0.1"/>'
    "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>"
    "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>40"
    '</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
    "</Domain></CycloneDDS>"
)


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
                busy_from = len(log.read_text())  # the ticks while the client publishes
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
                busy = log.read_text()[busy_from:]
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
    return {
        "db": latencies(out["toggles"], watcher.seen),
        "ros": latencies(out["toggles"], out["seen"]),
        "fox": latencies(out["toggles"], json.loads(fox_out)["seen"]) if fox_out else [],
        "toggles": len(out["toggles"]),
        **serve_stats(summary, busy),
    }


def serve_stats(summary: str, busy: str) -> dict[str, Any]:
    """Ticks, overruns, tick median and input waits from `toaster serve`'s log; ``busy_ms``:
    the median of the tick p50s of the status windows written while the client published
    (``busy``: that part of the log; the first window began before it). serve's own median
    counts the idle ticks before the client starts (ROS 1's client starts seconds later)."""
    windows = [float(x) for x in re.findall(r"window \d+ s: \d+ ticks, p50 ([\d.]+) ms", busy)]
    found = re.search(
        r"stopped after (\d+) ticks \((\d+) overran [\d.]+ ms; median ([\d.]+) ms", summary
    )
    ticks, overruns, median = found.groups() if found else ("nan", "nan", "nan")
    waits = re.findall(r"input waits p50 ([\d.]+) ms, p99 ([\d.]+) ms", summary)
    return {
        "wait": [float(w) for w in waits[-1]] if waits else [math.nan, math.nan],
        "ticks": float(ticks),
        "overruns": float(overruns),
        "tick_ms": float(median),
        "busy_ms": statistics.median(windows[1:]) if len(windows) > 1 else math.nan,
    }


def ros2_run(backend: str, pg: str, humans: int, seconds: float, tmp: str) -> dict[str, Any]:
    """One run with `toaster serve --ros2` and the cyclonedds client (live_client_ros2.py)."""
    database = Database(backend, pg, tmp)
    frames = Path(tmp) / f"frames{humans}.json"
    frames.write_text(json.dumps(frame_map(humans, 50)))
    config = Path(tmp) / "cyclonedds.xml"
    config.write_text(LOOPBACK)
    env = dict(os.environ, ROS_DOMAIN_ID=str(random.randint(1, 230)))
    env["CYCLONEDDS_URI"] = config.as_uri()
    try:
        put_zones(database.url, humans)
        log = Path(tmp) / "serve2.log"
        with log.open("w") as err:
            cmd = [sys.executable, "-m", "toaster", "--db", database.url, "serve", "--ros2"]
            node = subprocess.Popen(
                [*cmd, "--tf-map", str(frames), "--status-every", "2"],
                env=env,
                stderr=err,
                start_new_session=True,
            )
            while "(Ctrl-C stops)" not in log.read_text():
                if node.poll() is not None:
                    raise RuntimeError(log.read_text()[-2000:])
                time.sleep(0.05)
            watcher = Watcher(database.url)
            busy_from = len(log.read_text())  # the ticks while the client publishes
            client = subprocess.run(
                [
                    sys.executable,
                    str(HERE / "live_client_ros2.py"),
                    str(humans),
                    "50",
                    str(seconds),
                ],
                env=env,
                cwd=HERE,
                capture_output=True,
                text=True,
                timeout=seconds + 120,
            )
            watcher.close()
            busy = log.read_text()[busy_from:]
            os.killpg(node.pid, signal.SIGTERM)
            node.wait(30)
        if client.returncode != 0:
            raise RuntimeError(client.stderr[-2000:])
        out = json.loads(client.stdout.strip().splitlines()[-1])
        summary = log.read_text()
    finally:
        database.close()
    return {
        "db": latencies(out["toggles"], watcher.seen),
        "ros": latencies(out["toggles"], out["seen"]),
        "fox": [],
        "toggles": len(out["toggles"]),
        **serve_stats(summary, busy),
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
        "busy_ms": statistics.median(stats.tick_ms) if stats.tick_ms else float("nan"),
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
    parser.add_argument(
        "--ros2",
        action="store_true",
        help="also `toaster serve --ros2` with a cyclonedds client (needs toaster[ros2])",
    )
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.repeats, args.humans = 2.0, 1, "3"
    backends = ([] if args.only_pg else ["sqlite"]) + ([] if args.no_pg else ["postgresql"])
    print(
        f"Live latency, pose published -> fact (ms; median over {args.repeats} runs of each "
        f"run's p50 / p99; {args.seconds:.0f} s per run, 30 Hz, 50 objects, 2 joints per "
        "human; paths alternate; target p99 < 33 ms for 10 humans)"
    )
    print(
        f"{'path':<20} {'humans':>6} {'backend':<11} {'changes':>8} {'db p50':>7} "
        f"{'db p99':>7} {'ros p50':>8} {'ros p99':>8} {'tick ms':>8} {'busy p50':>9} "
        f"{'overruns':>9}"
        f" {'wait p50':>9} {'wait p99':>9}" + (" fox p50  fox p99" if args.foxglove else "")
    )
    paths: list[tuple[str, Any]] = [
        ("in-process (base)", api_run),
        (ROS1, ros_run),
    ]
    if args.foxglove:
        paths.append((FOX, functools.partial(ros_run, foxglove=True)))  # the same ticks
    if args.ros2:
        paths.append((ROS2, ros2_run))
    with tempfile.TemporaryDirectory() as tmp:
        for humans in (int(h) for h in args.humans.split(",")):
            for backend in backends:
                runs: dict[str, list[dict[str, Any]]] = {label: [] for label, _ in paths}
                for _ in range(args.repeats):
                    for label, run in paths:
                        runs[label].append(run(backend, args.pg, humans, args.seconds, tmp))
                for label, done in runs.items():
                    print(row(label, humans, backend, done, args.foxglove), flush=True)
                for line in ratios(runs):
                    print(line, flush=True)


ROS1, FOX, ROS2 = "toaster serve --ros1", "serve --ros1 --fox", "toaster serve --ros2"


def row(label: str, humans: int, backend: str, runs: list[dict[str, Any]], fox: bool) -> str:
    """One path's line of the table: medians over its runs."""

    def med(key: str, q: float) -> float:
        return statistics.median(pct(r[key], q) for r in runs)

    def mid(key: str, i: int | None = None) -> float:
        return statistics.median(r[key] if i is None else r[key][i] for r in runs)

    return (
        f"{label:<20} {humans:>6} {backend:<11} {mid('toggles'):>8.0f} "
        f"{med('db', 50):>7.1f} {med('db', 99):>7.1f} {med('ros', 50):>8.1f} "
        f"{med('ros', 99):>8.1f} {mid('tick_ms'):>8.1f} {mid('busy_ms'):>9.1f} "
        f"{mid('overruns'):>9.0f}"
        f" {mid('wait', 0):>9.1f} {mid('wait', 1):>9.1f}"
        + (f" {med('fox', 50):>8.1f} {med('fox', 99):>8.1f}" if fox else "")
    )


def ratios(runs: dict[str, list[dict[str, Any]]]) -> list[str]:
    """The ROS 2 FactList's and Foxglove's latency over the `--ros1` FactList's: each repeat's
    ratio (the paths alternate), median over repeats."""
    out = []
    base = runs[ROS1]
    for label, key, what in ((ROS2, "ros", "ROS 2 FactList"), (FOX, "fox", "Foxglove facts")):
        if label not in runs:
            continue
        parts = []
        for q in (50, 99):
            each = [
                pct(r[key], q) / pct(b["ros"], q) for r, b in zip(runs[label], base, strict=True)
            ]
            parts.append(
                f"p{q} {statistics.median(each):.2f}x ({', '.join(f'{x:.2f}' for x in each)})"
            )
        out.append(f"  {what} / ROS 1 FactList: {'; '.join(parts)}")
    return out


if __name__ == "__main__":
    main()
