"""Several robots writing one database for minutes, then `toaster db check` (issue 25).

Each writer is one robot running a long spatial Sally-Anne scene (the shipped 15 s scene
repeated: Sally leaves and comes back, the marble moves between basket and box, lids open and
close) as a live robot does: 30 Hz ticks paced by the wall clock (a late tick starts at once),
stamped with the scene's time, all robots starting together on one fresh database, so their
ticks share instants and lag one another as processes on a busy machine do. After
``--minutes`` each writer stops at its next tick; the table gives each writer's ticks, failed
ticks (one line per distinct error) and ticks that met a lock time-out (rolled back whole and
written again), then what ``toaster db check`` says.
Usage: python benchmarks/soak_writers.py --writers 8 --minutes 10 [--db URL] [--quick]
       (default: a fresh schema of the local PostgreSQL; ``--db sqlite`` a fresh file;
       ``--quick``: 2 writers for 3 s, nothing kept afterwards: a smoke run)
"""

from __future__ import annotations

import argparse
import collections
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from importlib import resources
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
SCENE = resources.files("toaster") / "examples" / "scenario_spatial_sally_anne.yaml"
CYCLE_S = 15
#: A tick that waited TOASTER_LOCK_TIMEOUT for SQLite's write lock (it has no fair queue:
#: other writers can take it again and again) was rolled back whole; it is written again, as a
#: live node does, this many times at most.
LOCKED_ATTEMPTS = 5


def long_scene(minutes: float, robot: str, folder: Path) -> Path:
    """The 15 s scene repeated for ``minutes``, its robot body named ``robot``."""
    scene = yaml.safe_load(re.sub(r"\bROBOT\b", robot, SCENE.read_text(encoding="utf-8")))
    cycles = int(minutes * 60 // CYCLE_S) + 2
    timeline = []
    for k in range(cycles):
        for step in scene["timeline"]:
            at = float(str(step["at"]).rstrip("s")) + k * CYCLE_S
            timeline.append({**step, "at": f"{at}s"})
    scene["timeline"] = timeline
    scene["duration"] = f"{cycles * CYCLE_S}s"
    path = folder / f"{robot}.yaml"
    path.write_text(yaml.safe_dump(scene), encoding="utf-8")
    return path


def writer(url: str, robot: str, scene: str, seconds: float, out: str) -> None:
    """One robot: tick at 30 Hz of wall time until ``seconds`` have passed."""
    import toaster
    from toaster.errors import DatabaseLockedError
    from toaster.producers import Runner, load_session

    errors: collections.Counter[str] = collections.Counter()
    ticks = locked = 0
    with toaster.connect(url) as db:
        store = db.store()
        session = load_session(scene, store.areas())
        runner = Runner(
            session.world,
            session.sources,
            session.producers,
            store=store,
            agent_id=robot,
            config=session.config,
        )
        session.register(store)
        step = round(1e9 / 30)
        wall0 = time.monotonic()
        for i, t in enumerate(range(session.start_ns, session.end_ns + 1, step)):
            now = time.monotonic()
            if now - wall0 >= seconds:
                break
            time.sleep(max(0.0, wall0 + i / 30 - now))
            for attempt in range(LOCKED_ATTEMPTS):
                try:
                    runner.tick(t)
                    ticks += 1
                    break
                except DatabaseLockedError:  # rolled back whole: wait for the lock again
                    locked += 1
                    store.forget()
                    if attempt == LOCKED_ATTEMPTS - 1:
                        errors["DatabaseLockedError (after retries)"] += 1
                except Exception as exc:  # counted and reported: the run must have none
                    errors[f"{type(exc).__name__}: {str(exc).splitlines()[0][:160]}"] += 1
                    break
    Path(out).write_text(
        json.dumps({"robot": robot, "ticks": ticks, "errors": errors, "locked": locked})
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--writers", type=int, default=8)
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--db", default="postgresql://postgres@127.0.0.1:5432/test")
    parser.add_argument("--quick", action="store_true", help="2 writers for 3 s (a smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.writers, args.minutes = 2, 0.05
    folder = Path(tempfile.mkdtemp(prefix="soak_writers_"))
    if args.db == "sqlite":
        url = f"sqlite:///{folder / 'soak.db'}"
    else:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from bench_writers import _drop, _schema

        url = _schema(args.db)
    try:
        soak(args.writers, args.minutes, url, folder)
    finally:
        if args.quick:  # a smoke run keeps nothing
            shutil.rmtree(folder, ignore_errors=True)
            if args.db != "sqlite":
                _drop(args.db, [url])


def soak(writers: int, minutes: float, url: str, folder: Path) -> None:
    """Run the writers on ``url``, print their rows and what ``toaster db check`` says."""
    print(f"database: {url}", flush=True)
    procs = []
    for i in range(writers):
        robot = f"R{i}"
        scene = long_scene(minutes, robot, folder)
        out = folder / f"{robot}.json"
        procs.append(
            (
                out,
                subprocess.Popen(
                    [
                        sys.executable,
                        __file__,
                        "--writer",
                        url,
                        robot,
                        str(scene),
                        str(minutes * 60),
                        str(out),
                    ],
                    cwd=ROOT,
                ),
            )
        )
    total, failed = 0, 0
    for out, proc in procs:
        proc.wait()
        report = json.loads(out.read_text())
        total += report["ticks"]
        failed += sum(report["errors"].values())
        print(
            f"{report['robot']}: {report['ticks']} ticks, "
            f"{sum(report['errors'].values())} failed {dict(report['errors'])}, "
            f"{report['locked']} lock time-outs written again",
            flush=True,
        )
    check = subprocess.run(
        [sys.executable, "-m", "toaster", "--db", url, "db", "check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    print(f"total: {total} ticks, {failed} failed; toaster db check: exit {check.returncode}")
    print((check.stdout + check.stderr).strip()[:4000])
    if failed or check.returncode:
        sys.exit(f"{failed} failed ticks, toaster db check exit {check.returncode}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--writer":
        writer(sys.argv[2], sys.argv[3], sys.argv[4], float(sys.argv[5]), sys.argv[6])
    else:
        main()
