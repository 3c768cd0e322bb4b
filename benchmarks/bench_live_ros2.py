"""Latency of `toaster serve --ros2` beside `toaster serve --ros1`, in the same run: a pose
published by another process -> (a) the fact in the database (a `toaster.queries.watch`
reader) and (b) the FactList received by that process. The scene is bench_live.py's (H humans
with 2 joints, 50 objects, /tf at 30 Hz, each human into and out of its zone once a second);
the ROS 2 side is live_client_ros2.py (cyclonedds, no toaster) on a random ROS_DOMAIN_ID over
loopback DDS. Runs alternate ROS 1 / ROS 2; quoted: medians over repeats of each run's p50 /
p99 in ms.

Run: .venv/bin/python benchmarks/bench_live_ros2.py [--seconds 10] [--repeats 3] [--humans 10]
     [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench_live import Watcher, frame_map, latencies, pct, put_zones, ros_run
from bench_run import Database

HERE = Path(__file__).resolve().parent
LOOPBACK = (
    '<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface address="127.0.0.1"/>'
    "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>"
    "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>40"
    '</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
    "</Domain></CycloneDDS>"
)


def ros2_run(humans: int, seconds: float, tmp: str) -> dict[str, Any]:
    """One run with `toaster serve --ros2` and the cyclonedds client."""
    database = Database("sqlite", "", tmp)
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
            os.killpg(node.pid, signal.SIGTERM)
            node.wait(30)
        if client.returncode != 0:
            raise RuntimeError(client.stderr[-2000:])
        out = json.loads(client.stdout.strip().splitlines()[-1])
        summary = log.read_text()
    finally:
        database.close()
    found = re.search(
        r"stopped after (\d+) ticks \((\d+) overran [\d.]+ ms; median ([\d.]+)", summary
    )
    ticks, overruns, median = found.groups() if found else ("nan", "nan", "nan")
    waits = re.findall(r"input waits p50 ([\d.]+) ms, p99 ([\d.]+) ms", summary)
    return {
        "wait": [float(w) for w in waits[-1]] if waits else [float("nan")] * 2,
        "db": latencies(out["toggles"], watcher.seen),
        "ros": latencies(out["toggles"], out["seen"]),
        "toggles": len(out["toggles"]),
        "ticks": int(ticks),
        "overruns": int(overruns),
        "tick_ms": float(median),
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--humans", default="10")
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.repeats, args.humans = 2.0, 1, "3"
    print(
        f"Live latency, pose published -> fact (ms; median over {args.repeats} runs of each "
        f"run's p50 / p99; {args.seconds:.0f} s per run, 30 Hz, 50 objects, SQLite; ROS 1 and "
        "ROS 2 runs alternate)"
    )
    print(
        f"{'path':<20} {'humans':>6} {'changes':>8} {'db p50':>7} {'db p99':>7} "
        f"{'ros p50':>8} {'ros p99':>8} {'tick ms':>8} {'overruns':>9}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for humans in (int(h) for h in args.humans.split(",")):
            runs: dict[str, list[dict[str, Any]]] = {"--ros1": [], "--ros2": []}
            for _ in range(args.repeats):
                runs["--ros1"].append(ros_run("sqlite", "", humans, args.seconds, tmp))
                runs["--ros2"].append(ros2_run(humans, args.seconds, tmp))
            for flag, done in runs.items():

                def med(key: str, q: float, done: list = done) -> float:
                    return statistics.median(pct(r[key], q) for r in done)

                print(
                    f"{'toaster serve ' + flag:<20} {humans:>6} "
                    f"{statistics.median(r['toggles'] for r in done):>8.0f} "
                    f"{med('db', 50):>7.1f} {med('db', 99):>7.1f} {med('ros', 50):>8.1f} "
                    f"{med('ros', 99):>8.1f} "
                    f"{statistics.median(r['tick_ms'] for r in done):>8.1f} "
                    f"{statistics.median(r['overruns'] for r in done):>9.0f}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
