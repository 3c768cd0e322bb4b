"""One writer (or reader) process of the many-writers test and benchmark.

``python -m tests.db.writers URL ROLE TICKS SEED OUT.json [PROGRESS]`` from the project root
(ROLE: ``ROBOT:rooms``, ``ROBOT:things``, ``reader`` or
``run:ROBOT:SCENARIO:RATE:TICKS[:HOLDERS[:live[:PEOPLE]]]``).
A writer
is one producer of one robot: it registers the robot (a self agent), the people and the
things (the same ids in every process, so registrations race), then writes a snapshot of its
source TICKS times, stamped with the wall clock as a live node stamps its ticks:
people walk between rooms (source ``rooms``), things move between containers (source
``things``). A reader asks what readers ask (current beliefs, diff, as of) TICKS times.
Work is counted, never timed: a process stops after TICKS ticks (or, failing that, after
:data:`TIMEOUT_S`, and the test names it as short). PROGRESS, if given, is a file holding
the number of ticks done so far (rewritten after each tick), for a test that waits for it.
The JSON out: ticks, failures (one line each), tick latencies (s), last snapshot.
"""

from __future__ import annotations

import json
import os
import random
import re
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

import toaster
from toaster.model import Fact

PEOPLE = ("ANNE", "BOB", "CARL", "DORA", "EVE")
ROOMS = ("KITCHEN", "HALL", "OFFICE")
CONTAINERS = {"BASKET": "KITCHEN", "BOX": "HALL", "DRAWER": "OFFICE"}
THINGS = ("MARBLE", "KEY", "CUP", "PEN")
#: Between two ticks a writer idles, as a producer ticking at up to 100 Hz does: SQLite has no
#: fair queue for its write lock, and writers that never pause can starve one another past
#: TOASTER_LOCK_TIMEOUT.
PAUSE_S = 0.01
#: A process that has not done its ticks after this long stops and reports how many it did.
TIMEOUT_S = 120.0


def register(db: toaster.Database, robot: str) -> None:
    """The robot (self), people (agents), rooms, containers and things."""
    store = db.store()
    with store.transaction():
        store.add_entity(robot, "robot", is_self=True, t_ns=0)
        for person in PEOPLE:
            store.add_entity(person, "human", t_ns=0)
        for entity in (*ROOMS, *CONTAINERS, *THINGS):
            store.add_entity(entity, "object", t_ns=0)


def snapshot(source: str, state: dict[str, str]) -> list[Fact]:
    """The facts of a source: where people are, or where things are."""
    prop = "IsInRoom" if source == "rooms" else "IsIn"
    facts = [Fact(who, prop, where) for who, where in sorted(state.items())]
    if source == "rooms":
        facts += [Fact(box, "IsInRoom", room) for box, room in CONTAINERS.items()]
    return facts


#: A file path: a ``run:`` writer, once registered, writes ``OUT.ready`` and waits for this
#: file before its first tick, so that a benchmark starts every robot's ticks together.
GO_VAR = "TOASTER_WRITERS_GO"


def _wait_for_go(out: str) -> None:
    go = os.environ.get(GO_VAR)
    if not go:
        return
    Path(f"{out}.ready").touch()
    deadline = time.monotonic() + TIMEOUT_S
    while not Path(go).exists() and time.monotonic() < deadline:
        time.sleep(0.01)


def _progress(path: str | None, ticks: int) -> None:
    if path:
        Path(path).write_text(str(ticks), encoding="utf-8")


def write(
    url: str, role: str, ticks: int, seed: int, progress: str | None = None
) -> dict[str, Any]:
    """``role`` is ``ROBOT:source``: ``ticks`` ticks (or what :data:`TIMEOUT_S` allows)."""
    robot, source = role.split(":")
    rng = random.Random(seed)
    failures: list[str] = []
    latencies: list[float] = []
    last: list[Fact] = []
    with toaster.connect(url) as db:
        for attempt in range(3):
            try:
                register(db, robot)
                break
            except Exception as exc:  # recorded: the test asserts there is none
                failures.append(f"register {attempt}: {type(exc).__name__}: {exc}"[:300])
        if source == "rooms":
            state = {p: rng.choice(ROOMS) for p in PEOPLE}
            choices: tuple[str, ...] = ROOMS
        else:
            state = {x: rng.choice(list(CONTAINERS)) for x in THINGS}
            choices = tuple(CONTAINERS)
        store = db.store()
        deadline = time.monotonic() + TIMEOUT_S
        while len(latencies) < ticks and time.monotonic() < deadline:
            t = time.time_ns()  # the robot's clock, as `toaster serve` stamps its ticks
            who = rng.choice(sorted(state))
            state[who] = rng.choice(choices)
            facts = snapshot(source, state)
            start = time.perf_counter()
            try:
                store.sync_many(robot, t, [(source, facts)])
                last = facts
            except Exception as exc:
                failures.append(f"tick {t}: {type(exc).__name__}: {exc}"[:300])
            latencies.append(time.perf_counter() - start)
            _progress(progress, len(latencies))
            time.sleep(PAUSE_S)
    return {
        "role": role,
        "ticks": len(latencies),
        "failures": failures,
        "latencies": latencies,
        "last": [list(f) for f in last],
    }


def read(url: str, ticks: int, seed: int) -> dict[str, Any]:
    """Ask what readers ask ``ticks`` times (or what :data:`TIMEOUT_S` allows)."""
    from toaster import queries
    from toaster.beliefs import api

    rng = random.Random(seed)
    failures: list[str] = []
    latencies: list[float] = []
    deadline = time.monotonic() + TIMEOUT_S
    with toaster.connect(url) as db:
        while len(latencies) < ticks and time.monotonic() < deadline:
            start = time.perf_counter()
            try:
                person = rng.choice(PEOPLE)
                api.beliefs(db, person)
                queries.current_facts(db, person, limit=50)
                queries.events(db, limit=50)
            except Exception as exc:
                if "unknown agent" not in str(exc):  # not registered yet: a fair answer
                    failures.append(f"read: {type(exc).__name__}: {exc}"[:300])
            latencies.append(time.perf_counter() - start)
            time.sleep(0.01)
    return {
        "role": "reader",
        "ticks": len(latencies),
        "failures": failures,
        "latencies": latencies,
        "last": [],
    }


def run(
    url: str,
    robot: str,
    path: str,
    rate: float,
    ticks: int,
    holders: str | None = None,
    pace: str = "",
    people: str = "shared",
    out: str = "",
) -> dict[str, Any]:
    """``toaster run PATH --rate RATE`` as robot ``robot`` (the library path of the command:
    load, register, tick) for at most ``ticks`` ticks, timing each tick. The scenario's self
    (its robot's body) is renamed ``robot``: each writer is its own robot in the same scene,
    and no other robot of the scene is a belief holder. ``pace`` "live":
    each tick starts at its time on the wall clock, as ``--realtime`` and a live node tick
    (a late tick starts at once); else ticks follow one another at once. ``people`` "own":
    the scene's humans are this robot's alone (renamed ``NAME_ROBOT``): robots whose holder
    sets are disjoint, as sites whose people never meet; else every robot sees the same
    people."""
    from toaster.producers import Runner, load_session

    failures: list[str] = []
    latencies: list[float] = []
    with toaster.connect(url) as db, tempfile.TemporaryDirectory() as tmp:
        store = db.store()
        session = load_session(path, store.areas(), holders=holders)
        renames = {session.self_id: robot} if session.self_id != robot else {}
        if people == "own":
            scene = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
            humans = [e["id"] for e in scene.get("entities", []) if e.get("kind") == "human"]
            renames.update({human: f"{human}_{robot}" for human in humans})
        if renames:  # the scene's robot body is this robot, under its id (and its people)
            text = Path(path).read_text(encoding="utf-8")
            for old, new in renames.items():
                text = re.sub(rf"\b{re.escape(old)}\b", new, text)
            mine = Path(tmp) / Path(path).name
            mine.write_text(text, encoding="utf-8")
            session = load_session(mine, store.areas(), holders=holders)
        runner = Runner(
            session.world,
            session.sources,
            session.producers,
            store=store,
            agent_id=robot,
            config=session.config,
        )
        try:
            session.register(store)
        except Exception as exc:
            failures.append(f"register: {type(exc).__name__}: {exc}"[:300])
        step = round(1e9 / rate)
        _wait_for_go(out)
        started = time.time()  # the ticks' span, comparable across processes
        wall0 = time.perf_counter()
        for i, t in enumerate(range(session.start_ns, session.end_ns + 1, step)[:ticks]):
            if pace == "live":
                time.sleep(max(0.0, wall0 + i / rate - time.perf_counter()))
            start = time.perf_counter()
            try:
                runner.tick(t)
            except Exception as exc:
                failures.append(f"tick {t}: {type(exc).__name__}: {exc}"[:300])
            latencies.append(time.perf_counter() - start)
    return {
        "role": f"run:{robot}",
        "ticks": len(latencies),
        "failures": failures,
        "latencies": latencies,
        "last": [],
        "span": [started, time.time()],
    }


def main(argv: list[str]) -> None:
    url, role, ticks, seed, out, *progress = argv
    if role == "reader":
        result = read(url, int(ticks), int(seed))
    elif role.startswith("run:"):  # run:ROBOT:PATH:RATE:TICKS[:HOLDERS[:live[:PEOPLE]]]
        _, robot, path, rate, run_ticks, *holders = role.split(":")
        result = run(url, robot, path, float(rate), int(run_ticks), *holders, out=out)
    else:
        result = write(url, role, int(ticks), int(seed), *progress)
    with open(out, "w", encoding="utf-8") as handle:
        json.dump(result, handle)


if __name__ == "__main__":
    main(sys.argv[1:])
