"""ToM-bAbI (tom_easy) replayed through the public API, questions answered from the database.

Each story becomes scenario steps (``X entered the R`` -> IsInRoom, ``The O is in the C`` and
``X moved the O to the C`` -> IsIn, the container placed in the actors' room); every question is
answered with :mod:`toaster.beliefs.api`: first order from the agent's beliefs, second order from
the nested holder ``A>B``, reality from the self agent, memory from the self agent's history.
The perceivers the rules infer (agents with a belief event at the line's time) are compared
with the observer ids of each line. Run: ``python -m tools.tombabi [ZIP] [--limit N]``.
"""

from __future__ import annotations

import re
import sys
import tempfile
import zipfile
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import toaster
from toaster import queries as q
from toaster.beliefs import api
from toaster.beliefs.scenario import Replayer, Scenario, Step
from toaster.db.catalog import note_data_start

SELF = "ROBOT"
_ENTER = re.compile(r"^(\w+) (entered|exited) the (\w+)\.$")
_IS_IN = re.compile(r"^The (\w+) is in the (\w+)\.$")
_MOVED = re.compile(r"^(\w+) moved the (\w+) to the (\w+)\.$")
_Q_FIRST = re.compile(r"^Where will (\w+) look for the (\w+)\?$")
_Q_SECOND = re.compile(r"^Where does (\w+) think that (\w+) searches for the (\w+)\?$")
_Q_REAL = re.compile(r"^Where is the (\w+) really\?$")
_Q_MEM = re.compile(r"^Where was the (\w+) at the beginning\?$")


def stories(lines: list[str]) -> list[list[str]]:
    """Split a file into stories (numbering restarts at 1)."""
    out: list[list[str]] = []
    for line in lines:
        if not line.strip():
            continue
        if line.split(" ", 1)[0] == "1":
            out.append([])
        out[-1].append(line.rstrip("\n"))
    return out


def _where(db: Any, holder: str, about: str | None, obj: str) -> str | None:
    rows = api.beliefs(db, holder, about, subject=obj, property="IsIn")
    return rows[0].target_id if len(rows) == 1 else None


class StoryResult:
    """Answer correctness and perceiver agreement of one story."""

    def __init__(self) -> None:
        self.correct = 0
        self.total = 0
        self.misses: list[str] = []
        self.perceiver_lines = 0
        self.perceiver_mismatches: list[str] = []


def replay_story(db: Any, story: list[str]) -> StoryResult:
    """Replay one story into an emptied database and answer its question(s), in one
    transaction (the questions read what it wrote so far). Its people are registered without
    per-agent views (DDL no question reads), and the perceivers of every line are read in one
    query at the end."""
    store = db.store()
    with store.transaction() as conn:
        store.empty()
        note_data_start(conn, 0)
        store.add_entity(SELF, "robot", is_self=True, t_ns=0, views=False)
        return _replay(db, store, story)


def _replay(db: Any, store: Any, story: list[str]) -> StoryResult:
    result = StoryResult()
    agents: list[str] = []
    rooms: dict[str, str] = {}  # agent -> room
    ids: dict[str, str] = {}  # observer id -> agent
    observed: list[tuple[int, str, set[str]]] = []  # (time, sentence, its observers' agents)
    replayer = Replayer(db, Scenario("tom", SELF, [], [], {}, [], []))
    room = ""
    for line in story:
        number, rest = line.split(" ", 1)
        parts = rest.split("\t")
        sentence = parts[0].strip()
        t_ns = int(number) * 1_000_000_000
        if len(parts) == 3:  # a question
            answer = _answer(db, sentence)
            result.total += 1
            if answer == parts[1]:
                result.correct += 1
            else:
                result.misses.append(f"{sentence} -> {answer!r}, expected {parts[1]!r}")
            continue
        observers = parts[1].split() if len(parts) > 1 else []
        step = Step(t_ns)
        if m := _ENTER.match(sentence):
            name, verb, where = m.groups()
            if name not in agents:
                agents.append(name)
                store.add_entity(name, "human", t_ns=0, views=False)
            if verb == "entered":
                room = where
                rooms[name] = where
                step.rooms[name] = where
                new = [o for o in observers if o not in ids]
                if len(new) == 1:
                    ids[new[0]] = name
            else:
                rooms.pop(name, None)
                step.rooms[name] = None
        elif m := _IS_IN.match(sentence):
            obj, container = m.groups()
            step.rooms[container] = room
            step.inside[obj] = ("IsIn", container)
        elif m := _MOVED.match(sentence):
            actor, obj, container = m.groups()
            step.rooms[container] = rooms.get(actor, room)
            step.inside[obj] = ("IsIn", container)
            step.actor = actor if actor in agents else None
        elif sentence != "Phone rang.":
            result.misses.append(f"unparsed sentence {sentence!r}")
            continue
        if step.rooms or step.inside:
            replayer.apply(step)
        if observers:
            observed.append((t_ns, sentence, {ids.get(o, f"?{o}") for o in observers}))
    _check_perceivers(db, result, observed, set(agents))
    return result


def _check_perceivers(
    db: Any, result: StoryResult, observed: list[tuple[int, str, set[str]]], agents: set[str]
) -> None:
    """Compare, line by line, the agents with a belief event at the line's time (the
    perceivers the rules inferred) with the line's observers."""
    if not observed:
        return
    seen: dict[int, set[str]] = defaultdict(set)
    first, last = observed[0][0], observed[-1][0]
    for event in q.events(db, since=first, until=last):
        if event.agent_id in agents:
            seen[event.stamp_ns].add(event.agent_id)
    for t_ns, sentence, expected in observed:
        result.perceiver_lines += 1
        if seen[t_ns] != expected:
            result.perceiver_mismatches.append(
                f"{sentence}: rules {sorted(seen[t_ns])}, line {sorted(expected)}"
            )


def _answer(db: Any, question: str) -> str | None:
    if m := _Q_FIRST.match(question):
        return _where(db, m.group(1), None, m.group(2))
    if m := _Q_SECOND.match(question):
        return _where(db, m.group(1), m.group(2), m.group(3))
    if m := _Q_REAL.match(question):
        return _where(db, SELF, None, m.group(1))
    if m := _Q_MEM.match(question):
        rows = q.history(db, SELF, subject=m.group(1), property="IsIn")
        return rows[0].target_id if rows else None
    return None


def evaluate(
    zip_path: Path, url: str, *, limit: int | None = None, noise: tuple[str, ...] = ("0", "10")
) -> dict[str, Any]:
    """Replay every test story (or the first ``limit`` per file); return accuracy tables."""
    db = toaster.connect(url)
    table: dict[tuple[str, str], list[int]] = defaultdict(lambda: [0, 0])
    misses: list[str] = []
    perceivers: Counter[str] = Counter()
    try:
        with zipfile.ZipFile(zip_path) as zf:
            for name in sorted(zf.namelist()):
                m = re.search(r"world_large_nex_1000_(\d+)/(\w+?)_(\w+)_test_test\.txt$", name)
                if not m or m.group(1) not in noise:
                    continue
                lines = zf.read(name).decode().splitlines()
                for story in stories(lines)[:limit]:
                    res = replay_story(db, story)
                    cell = table[(f"noise {m.group(1)}", f"{m.group(2)}_{m.group(3)}")]
                    cell[0] += res.correct
                    cell[1] += res.total
                    misses.extend(f"{name}: {x}" for x in res.misses)
                    perceivers["lines"] += res.perceiver_lines
                    perceivers["mismatches"] += len(res.perceiver_mismatches)
                    misses.extend(f"{name}: perceivers {x}" for x in res.perceiver_mismatches)
    finally:
        db.close()
    return {"table": dict(table), "misses": misses, "perceivers": dict(perceivers)}


def main(argv: list[str]) -> int:
    """Print the accuracy table per set and question type."""
    if "--help" in argv or "-h" in argv:
        print("usage: python -m tools.tombabi [ZIP] [--limit N] [--db URL]")
        return 0
    zip_path = (
        Path(argv[0])
        if argv and not argv[0].startswith("--")
        else Path("../shared/data/tom-babi/tom_easy.zip")
    )
    limit = int(argv[argv.index("--limit") + 1]) if "--limit" in argv else None
    url = argv[argv.index("--db") + 1] if "--db" in argv else None
    with tempfile.TemporaryDirectory() as tmp:
        out = evaluate(zip_path, url or f"sqlite:///{tmp}/tom.db", limit=limit)
    print(f"{'set':9} {'task_question':16} {'correct':>8} {'total':>6} {'accuracy':>9}")
    for (nset, task), (ok, total) in sorted(out["table"].items()):
        print(f"{nset:9} {task:16} {ok:8d} {total:6d} {100 * ok / max(total, 1):8.2f}%")
    print(f"perceiver check: {out['perceivers']}")
    for miss in out["misses"][:20]:
        print("MISS", miss)
    return 0 if not out["misses"] else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
