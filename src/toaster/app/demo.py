"""The demo: the whole job on the shipped spatial Sally-Anne scenario, in a few seconds.

Geometry (boxes, poses, lines of sight) becomes facts (IsOn, IsIn, IsClosed, CanSee); the belief
rules give Sally her own beliefs, false once Anne moves the marble out of her sight; a plain SQL
query on the belief tables shows it; a timeline picture draws it.

>>> import toaster
>>> from toaster.app.demo import run_demo                                  # doctest: +SKIP
>>> with toaster.connect("sqlite:///sally.db") as db:                  # doctest: +SKIP
...     print(run_demo(db, "sally.png").story())
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from toaster.errors import InvalidInputError, MissingDependencyError

if TYPE_CHECKING:
    from toaster.beliefs.api import BeliefDiff
    from toaster.db.database import Database
    from toaster.model import EventRow
    from toaster.outputs.plotting import Divergence
    from toaster.producers import Stats
    from toaster.queries.sql import SQLResult
    from toaster.timeutil import TimeFrame

SCENARIO = "scenario_spatial_sally_anne.yaml"
ROBOT, SALLY, ANNE = "ROBOT", "SALLY", "ANNE"
MARBLE = "MARBLE"
PLACES = ("IsOn", "IsIn")
#: What the story shows of the robot's events: (subject, property, target or None = any).
SEEN = (
    (MARBLE, "IsOn", None),
    (MARBLE, "IsIn", None),
    ("BASKET", "IsClosed", None),
    ("BOX", "IsClosed", None),
    (SALLY, "CanSee", "BASKET"),
)
#: Moments of the scenario's timeline (times since its start, as ``--at`` takes them) the
#: story asks about.
MOMENTS = (
    ("2s", "Sally walks out"),
    ("8s", "Anne has moved the marble"),
    ("13s", "Sally is back, boxes closed"),
    ("15s", "Sally has opened the basket"),
)
#: The plain SQL the story runs (read-only) on the belief tables: where each holder thinks
#: the marble is, and when. ``ANNE>SALLY`` is Anne's model of Sally's beliefs.
SQL = """SELECT agent_id, property, target_id, valid_from_ns, valid_to_ns
FROM fact_history
WHERE subject_id = 'MARBLE' AND property IN ('IsOn', 'IsIn')
  AND agent_id IN ('ROBOT', 'SALLY', 'ANNE>SALLY')
ORDER BY agent_id, valid_from_ns"""


@dataclass(frozen=True)
class Moment:
    """Where the robot, Sally and Anne's model of Sally think the marble is at ``t_ns``
    (``"IsIn BASKET"``; empty: nowhere they know of), and Sally's false beliefs about it then
    (the false-belief report against the robot, :func:`toaster.beliefs.api.false_beliefs`)."""

    t_ns: int
    what: str
    robot: tuple[str, ...]
    sally: tuple[str, ...]
    anne_on_sally: tuple[str, ...]
    false: tuple[BeliefDiff, ...]


@dataclass(frozen=True)
class Demo:
    """What :func:`run_demo` did and found; :meth:`story` tells it."""

    where: str  # the database, password hidden
    scenario: Path
    stats: Stats
    seconds: float  # wall time of the run
    frame: TimeFrame
    seen: tuple[EventRow, ...]
    moments: tuple[Moment, ...]
    sql: str
    result: SQLResult
    picture: Path
    companion: Path | None  # the gnuplot script beside a .dat picture
    divergences: tuple[Divergence, ...]  # Sally's false beliefs about the marble (intervals)
    note: str = ""  # why the picture is data rather than a PNG, and what to install

    def story(self) -> str:
        """The demo told in a few short sections, ending with commands to go further."""
        return "\n".join(_story(self))


@contextmanager
def scenario_file() -> Iterator[Path]:
    """The shipped scenario as a file on disk (for as long as the ``with`` lasts)."""
    with resources.as_file(resources.files("toaster") / "examples" / SCENARIO) as path:
        yield path


def check_picture(picture: str | Path) -> Path:
    """``picture`` as a path the demo can write (a known suffix, an existing folder), or a
    one-line error naming it and the fix."""
    from toaster.outputs.plotting import output_format

    path = Path(picture)
    output_format(path)
    if not path.parent.is_dir():
        msg = f"cannot draw {str(path)!r}: its folder does not exist; give an existing one"
        raise InvalidInputError(msg)
    return path


def run_demo(
    db: Database,
    picture: str | Path,
    *,
    time_style: str = "auto",
    on_tick: Callable[[int, int], None] | None = None,
) -> Demo:
    """Run the spatial Sally-Anne scenario into ``db`` (which must hold no facts), ask it what
    Sally believes, run the demo's SQL read-only and draw the marble's timeline to ``picture``
    (a ``.dat`` gnuplot file beside it when matplotlib, the ``plot`` extra, is missing).
    ``time_style`` says how the story shows times (:class:`toaster.timeutil.TimeFrame`);
    ``on_tick(done, total)`` is called after every tick (a progress bar). Bad input (a
    database with facts, a picture it cannot write) fails before anything is written."""
    from sqlalchemy.engine import make_url

    from toaster import queries as q
    from toaster.app.runs import run_file

    where = make_url(db.url).render_as_string(hide_password=True)
    picture = check_picture(picture)
    if q.history(db, limit=1):
        msg = f"the demo needs an empty database: {where} already holds facts; give a new one"
        raise InvalidInputError(msg)
    with scenario_file() as path:
        report = run_file(path, db, progress=on_tick)
    frame = db.time_frame(time_style)
    seen = tuple(
        e
        for e in q.events(db, ROBOT, subject=[s for s, _, _ in SEEN])
        if any(
            e.subject_id == s and e.property == p and t in (None, e.target_id) for s, p, t in SEEN
        )
    )
    moments = tuple(_moment(db, frame.parse(at), what) for at, what in MOMENTS)
    result = q.execute(db, SQL)
    out, companion, timeline, note = _picture(db, picture)
    false = tuple(d for d in timeline.divergences if d.agent == SALLY and d.kind == "false_belief")
    return Demo(
        where,
        path,
        report.stats,
        report.wall_s,
        frame,
        seen,
        moments,
        SQL,
        result,
        out,
        companion,
        false,
        note,
    )


def _moment(db: Database, t_ns: int, what: str) -> Moment:
    from toaster.beliefs import api

    def places(agent: str, about: str | None = None) -> tuple[str, ...]:
        rows = api.beliefs(db, agent, about, at=t_ns, subject=MARBLE, property=list(PLACES))
        return tuple(f"{r.property} {r.target_id}" for r in rows)

    false = tuple(
        d
        for d in api.false_beliefs(db, SALLY, at=t_ns)
        if d.subject_id == MARBLE and d.property in PLACES and d.value_a is not None
    )
    return Moment(t_ns, what, places(ROBOT), places(SALLY), places(ANNE, SALLY), false)


def _picture(db: Database, picture: Path) -> tuple[Path, Path | None, Any, str]:
    """The marble's timeline for the robot, Sally and Anne; gnuplot data when matplotlib is
    missing (with the note saying how to get the picture)."""
    from toaster.outputs.plotting import plot_facts

    def plot(path: Path) -> Any:
        return plot_facts(
            db,
            path,
            subject=MARBLE,
            property=list(PLACES),
            agents=[ROBOT, SALLY, ANNE],
            title="Where is the marble? (red hatching: Sally's false belief)",
        )

    try:
        result = plot(picture)
        note = ""
    except MissingDependencyError as exc:
        result = plot(picture.with_suffix(".dat"))
        note = f"{exc}; wrote the timeline as gnuplot data instead"
    return result.path, result.companion, result.timeline, note


def _columns(rows: list[list[str]], indent: str = "   ") -> list[str]:
    """Rows of cells as aligned text columns."""
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return [
        indent + "  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip()
        for row in rows
    ]


def _cell(name: str, value: Any, frame: TimeFrame) -> str:
    if value is None:
        return "(current)" if name == "valid_to_ns" else ""
    if name.endswith("_ns") and isinstance(value, int):
        return frame.show(value)
    return str(value)


def _story(demo: Demo) -> Iterator[str]:
    show, stats = demo.frame.show, demo.stats
    yield (
        f"Sally-Anne from geometry: {demo.scenario.name} run into {demo.where}, "
        f"{stats.ticks} ticks in {demo.seconds:.1f} s"
    )
    times = "seconds since the scenario's start" if demo.frame.elapsed else "dates (UTC)"
    yield f"({stats.facts} facts computed, {stats.events} changes stored; times are {times})"
    yield ""
    yield "1. What the robot sees: facts from boxes, poses and lines of sight (+ begins, - ends)"
    sign = {"appeared": "+", "ended": "-", "changed": "~"}
    yield from _columns(
        [
            [
                show(e.stamp_ns),
                sign.get(e.kind, e.kind),
                " ".join(filter(None, (e.subject_id, e.property, e.target_id))),
            ]
            for e in demo.seen
        ]
    )
    yield ""
    yield "2. Where each one thinks the marble is (Sally's beliefs, kept by the database)"
    rows = [["time", "moment", "ROBOT", "SALLY", "ANNE>SALLY", ""]]
    for m in demo.moments:
        flag = "<- Sally's false belief" if m.false else ""
        rows.append(
            [show(m.t_ns), m.what, _place(m.robot), _place(m.sally), _place(m.anne_on_sally), flag]
        )
    yield from _columns(rows)
    yield "   (ANNE>SALLY: what Anne thinks Sally believes; nowhere: no belief about it)"
    for d in demo.divergences:
        lane = d.lane.removeprefix(f"{MARBLE} ")
        yield (
            f"   Sally's false belief: the marble {lane} from {show(d.start_ns)} (Anne moves it "
            "while Sally is away)"
        )
        yield f"   to {show(d.end_ns)} (Sally opens the basket and finds it empty)."
    yield ""
    yield "3. The same from plain SQL (read-only, the library's execute path):"
    yield from ("   " + line for line in demo.sql.splitlines())
    columns = demo.result.columns
    cells = [
        [_cell(n, v, demo.frame) for n, v in zip(columns, row, strict=True)]
        for row in demo.result.rows
    ]
    yield ""
    yield from _columns([list(columns), *cells])
    yield ""
    yield f"4. The timeline: {demo.picture.resolve()}"
    if demo.note:
        yield f"   {demo.note}"
        if demo.companion is not None:
            yield f"   draw it with: gnuplot -p {demo.companion}"
    yield ""
    yield from _next_commands(demo)


def _place(places: tuple[str, ...]) -> str:
    return ", ".join(places) or "nowhere"


def _next_commands(demo: Demo) -> Iterator[str]:
    opt = f"--db {demo.where} "  # (a hidden password shows as ***: put yours)
    sql = (
        "SELECT agent_id, target_id, valid_from_ns, valid_to_ns FROM fact_history "
        "WHERE subject_id = 'MARBLE' AND property = 'IsIn'"
    )
    yield "Go further:"
    yield from _columns(
        [
            [f"toaster {opt}beliefs diff SALLY --at 10s", "# all Sally gets wrong 10 s in"],
            [f"toaster {opt}beliefs show ANNE --about SALLY --at 10s", "# Anne's model of Sally"],
            [
                f"toaster {opt}get-info EVENT --agent SALLY --subject MARBLE",
                "# how her beliefs changed",
            ],
            [f"toaster {opt}plot-facts marble.png --subject MARBLE", "# everything about it"],
        ],
        indent="  ",
    )
    yield f'  toaster {opt}execute SQL "{sql}"'
    yield f"  toaster --db sqlite:///sally.db run {demo.scenario}"
