"""Nothing a data source writes runs code or escapes (issue 24).

Ids and values with backquotes, ``$()``, quotes of every kind, line breaks, tabs, backslashes,
control characters, spreadsheet formulas, gnuplot and matplotlib markup, rich markup and a
10 kB id are stored through the real store (the library, ``toaster set-info`` and the
``fact_inbox`` table of plain SQL clients), written in every format toaster writes for another
program, and read by that program: gnuplot runs the script (nothing runs, the labels show the
ids), matplotlib draws no math, pandas, pyarrow and ``json`` read the exports back exactly,
a shell and a terminal show the ids, Debian's rosbag, rosbags and mcap open the recordings.
"""

from __future__ import annotations

import csv
import io
import json
import os
import pty
import re
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from click.testing import CliRunner

import toaster
from tests.outputs.conftest import (
    SYSTEM_PYTHON,
    open_built,
    require_gnuplot,
    require_system_rosbag,
)
from toaster import Fact
from toaster.cli import cli
from toaster.db.views import quote_identifier
from toaster.model import MAX_ID_BYTES
from toaster.outputs.export import export, read_frame, read_rows, select_rows
from toaster.outputs.plotting import plot_facts
from toaster.quoting import (
    CSV_MARK,
    FORMULA_START,
    ROS_TOKEN,
    csv_text,
    csv_untext,
    gnuplot_string,
    json_line,
    label_text,
    ros_id,
    ros_name,
    shell_word,
    visible,
)

S = 1_000_000_000
T0 = 1_700_000_000 * S
MARK = "PWNED"  # every injected command would create a file whose name starts with this
HOSTILE = [
    f"`touch {MARK}_bq`",
    f"$(touch {MARK}_dollar)",
    "$(touch X)",
    "it's",
    'say "hi"',
    "“curly” ‘single’ `back`",
    "two\nlines",
    "tab\there",
    "back\\slash\\",
    "ctl\x01\x7f\x9b",
    "\x1b[31mred\x1b]0;title\x07",
    "cr\rreturn",
    '=HYPERLINK("http://example.com","click")',
    "+cmd|' /C calc'!A0",
    "-1+1",
    "@SUM(1+1)",
    "'quote first",
    "\tleading tab",
    "^_{x}@&~ b{c}",
    "$x$ and $\\alpha$",
    "_legend",
    "a b",
    "x/../y",
    "x0abc",
    "[/x][red]r[/red]",
    "\u202eevil",
    "%s %n {0}",
]
#: The longest id the database takes from anyone (MAX_ID_BYTES; fact_inbox refuses longer
#: since revision 0030), written through fact_inbox (plain SQL): lines of shell and formulas
LONG = (f'`touch {MARK}_long` $(touch {MARK}_long) "=1+1"\n' * 300)[:MAX_ID_BYTES]
HELD = "MUG"  # every hostile agent believes MUG Distance TABLE (a number, -1.5)
CREATED = re.compile(rf"^({MARK}|X$)")


def build_hostile(db: toaster.Database) -> None:
    """ROBOT (self); every hostile id as a human agent holding MUG Distance TABLE = -1.5 m;
    the robot's MUG Says with every hostile id as its value in turn; facts between hostile
    subjects and targets; the longest id as a subject and a value inserted into fact_inbox."""
    store = db.store()
    store.add_entity("ROBOT", "robot", is_self=True, t_ns=T0)
    for name in (*HOSTILE, HELD, "TABLE"):
        store.add_entity(name, "object" if name in (HELD, "TABLE") else "human", t_ns=T0)
    for name in HOSTILE:
        store.assert_fact(name, Fact(HELD, "Distance", "TABLE", "far", -1.5, 0.9), t_ns=T0 + S)
    for k, name in enumerate(HOSTILE):
        store.assert_fact("ROBOT", Fact(HELD, "Says", "", name), t_ns=T0 + (2 + k) * S)
    for subject, target in pairwise(HOSTILE):
        store.assert_fact("ROBOT", Fact(subject, "IsOn", target), t_ns=T0 + S)
    with db.transaction() as conn:
        conn.execute(
            sa.text(
                "INSERT INTO fact_inbox (agent_id, subject_id, property, target_id, "
                "value_text, t_ns) VALUES ('ROBOT', :id, 'IsIn', '', :id, :t)"
            ),
            {"id": LONG, "t": T0 + 3 * S},
        )


@pytest.fixture
def hostile_db(db_url: str) -> Any:
    """A database holding :func:`build_hostile` (SQLite file and PostgreSQL)."""
    yield from open_built(db_url, build_hostile)


@pytest.fixture
def hostile_sqlite(tmp_path: Path) -> Any:
    """:func:`build_hostile` on SQLite (for consumers that read files, not databases)."""
    yield from open_built(f"sqlite:///{tmp_path / 'hostile.db'}", build_hostile)


def _created(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if CREATED.match(p.name))


# -- gnuplot ------------------------------------------------------------------------------------
def test_plot_facts_dat_runs_no_command_in_gnuplot(tmp_path: Path) -> None:
    """The finding as reported: an entity id with backquotes, stored with ``toaster set-info``,
    plotted with ``plot-facts out.dat`` and drawn by gnuplot, runs nothing."""
    gnuplot = require_gnuplot()
    url = f"sqlite:///{tmp_path / 'gp.db'}"
    for args in (
        ["set-info", "ENTITY", "--id", "ROBOT", "--type", "robot", "--self"],
        ["set-info", "ENTITY", "--id", f"`touch {MARK}`", "--type", "object"],
        [
            "set-info",
            "FACT",
            "--subject",
            f"`touch {MARK}`",
            "--property",
            "IsOn",
            "--target",
            "ROBOT",
            "--at",
            "1s",
        ],
        ["plot-facts", str(tmp_path / "out.dat")],
    ):
        done = CliRunner().invoke(cli, ["--db", url, *args])
        assert done.exit_code == 0, done.output
    drawn = subprocess.run(
        [gnuplot, "-e", "set terminal dumb", "out.gp"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert drawn.returncode == 0, drawn.stderr
    assert _created(tmp_path) == []
    assert f"`touch {MARK}` IsOn ROBOT" in drawn.stdout


def _svg_texts(path: Path) -> list[str]:
    """Every text element of an SVG, as an XML parser reads it."""
    return [
        "".join(element.itertext())
        for element in ET.parse(path).iter("{http://www.w3.org/2000/svg}text")
    ]


def _gnuplot_column(gnuplot: str, data: Path, index: int, rows: int, folder: Path) -> str:
    """Column 5 of the first ``rows`` lines of block ``index`` as gnuplot reads it
    (``strcol(5)``) and prints it, one value a line."""
    out = folder / f"column{index}.txt"
    done = subprocess.run(
        [
            gnuplot,
            "-e",
            f"set print {gnuplot_string(str(out))}; "
            f"do for [i=0:{rows - 1}] {{ stats {gnuplot_string(str(data))} "
            f"index {index} every ::i::i using (s = strcol(5), 0) nooutput; "
            "print s }",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return out.read_bytes().decode("utf-8")  # as printed: a carriage return stays one


@pytest.mark.slow
def test_gnuplot_script_runs_nothing_and_labels_show_the_ids(
    hostile_sqlite: toaster.Database, tmp_path: Path
) -> None:
    """The .gp and .dat under a hostile file name: gnuplot runs the script (by its path and on
    standard input) with exit 0, no injected command runs, the SVG it draws holds every id as
    a label (titles, key titles, y tics, shown verbatim: no enhanced-text markup), and the data
    file's value column reads back one field per line."""
    gnuplot = require_gnuplot()
    out_dir, run_dir = tmp_path / "out", tmp_path / "run"
    out_dir.mkdir()
    run_dir.mkdir()
    name = f"it's $(touch {MARK}_name)\n`touch {MARK}_file`.dat"
    result = plot_facts(hostile_sqlite, out_dir / name, max_facts=0)
    assert result.companion is not None
    script = result.companion.read_text(encoding="utf-8")
    assert f"gnuplot -p {visible(shell_word(result.companion.name))}" in script
    for how in ("path", "stdin"):
        svg = run_dir / f"{how}.svg"
        terminal = f"set terminal svg size 1200,4000; set output {gnuplot_string(str(svg))}"
        command = [gnuplot, "-e", terminal, str(result.companion)] if how == "path" else [gnuplot]
        done = subprocess.run(
            command,
            input=None if how == "path" else f"{terminal}\n{script}",
            cwd=run_dir,
            capture_output=True,
            text=True,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        assert "error" not in done.stderr.lower(), done.stderr
        assert _created(tmp_path) == [], how
        texts = _svg_texts(svg)
        titles = [t for t in texts if " IsOn " in t]
        for name_ in HOSTILE:
            assert visible(name_) in texts, (how, name_)  # key title and y tic, verbatim
            assert any(visible(name_) in t for t in titles), (how, name_)
        assert label_text(LONG) in texts  # a y tic (cut: the data file holds it whole)
        assert label_text(f"{LONG} IsIn") in texts  # its title
    blocks = result.path.read_text(encoding="utf-8").split("\n\n\n")
    says = next(i for i, block in enumerate(blocks) if f"# fact: {HELD} Says" in block)
    assert len(blocks[says].splitlines()) == 1 + 1 + len(HOSTILE) + 1  # head, "-", values, end
    read = _gnuplot_column(gnuplot, result.path, says, len(HOSTILE) + 2, tmp_path)
    assert read == "".join(f"{v}\n" for v in ("-", *HOSTILE, HOSTILE[-1]))


# -- matplotlib ---------------------------------------------------------------------------------
def _mpl_shown(figure: Any) -> list[str]:
    """What each text of ``figure`` shows, as matplotlib interprets it; none is math."""
    from matplotlib.text import Text

    out = []
    for text in figure.findobj(Text):
        raw = text.get_text()
        assert not text.get_usetex(), raw
        shown, math = text._preprocess_math(raw)  # matplotlib's own reading of the string
        assert math is False, raw
        out.append(shown)
    return out


@pytest.mark.slow
def test_matplotlib_draws_ids_as_text(hostile_sqlite: toaster.Database, tmp_path: Path) -> None:
    """PNG, SVG and PDF: no label is math text or LaTeX (even under a matplotlibrc that asks
    for LaTeX), every id shows as its visible text (an id starting with _ stays in the legend),
    and the SVG is well-formed XML whose number lines keep their ids."""
    mpl = pytest.importorskip("matplotlib")
    for fmt in ("png", "svg", "pdf"):
        with warnings.catch_warnings(record=True) as caught, mpl.rc_context({"text.usetex": True}):
            warnings.simplefilter("always")
            result = plot_facts(hostile_sqlite, tmp_path / f"p.{fmt}", max_facts=0)
        noted = [str(w.message) for w in caught]
        assert not [n for n in noted if "legend" in n or "Glyph" in n or "math" in n], noted
        shown = _mpl_shown(result.figure)
        for name in HOSTILE:
            assert visible(name).strip() in [s.strip() for s in shown], (fmt, name)
        legend = [
            t.get_text()
            for ax in result.figure.axes
            if ax.get_legend()
            for t in ax.get_legend().get_texts()
        ]
        assert " _legend" in legend
    ids = {el.get("id") for el in ET.parse(tmp_path / "p.svg").iter()}
    lane = next(lane for lane in result.timeline.lanes if lane.key.property == "Distance")
    from toaster.outputs.plotting.render import number_gid

    assert {number_gid(lane, name) for name in HOSTILE} <= ids
    assert (tmp_path / "p.png").stat().st_size > 10_000
    assert (tmp_path / "p.pdf").read_bytes().startswith(b"%PDF")


# -- exports ------------------------------------------------------------------------------------
TEXT_FIELDS = (
    "agent_id",
    "subject_id",
    "subject_owner_id",
    "property",
    "property_type",
    "sub_property",
    "target_id",
    "target_owner_id",
    "value_text",
    "source",
)


@pytest.mark.slow
def test_exports_read_back_exactly(hostile_db: toaster.Database, tmp_path: Path) -> None:
    """CSV, JSON lines and Parquet of the history: pandas and pyarrow read every id back
    exactly (CSV after the reader strips the one leading ' of a neutralised cell), the raw CSV
    cell a spreadsheet sees never starts with a formula character, numbers stay numbers,
    JSON lines are ASCII, Parquet metadata holds no id; read_rows and read_frame round trip."""
    pd = pytest.importorskip("pandas")
    pq = pytest.importorskip("pyarrow.parquet")
    rows = select_rows(hostile_db, "history")
    assert {*HOSTILE, LONG} <= {r.subject_id for r in rows} | {r.target_id for r in rows}
    for fmt in ("csv", "jsonl", "parquet"):
        path = tmp_path / f"history.{fmt}"
        export(hostile_db, "history", path)
        assert read_rows(path, "history") == rows, fmt
        assert len(read_frame(path, "history")) == len(rows)
    with (tmp_path / "history.csv").open(newline="", encoding="utf-8") as handle:
        raw = list(csv.DictReader(handle))
    for record, row in zip(raw, rows, strict=True):
        for field in TEXT_FIELDS:
            cell, value = record[field], getattr(row, field)
            assert not cell.startswith(FORMULA_START), cell
            assert cell == (
                CSV_MARK + value if value.startswith((*FORMULA_START, CSV_MARK)) else value
            )
    frame = pd.read_csv(
        tmp_path / "history.csv", dtype=dict.fromkeys(TEXT_FIELDS, str), keep_default_na=False
    )
    assert [csv_untext(v) for v in frame.subject_id] == [r.subject_id for r in rows]
    numbers = pd.read_csv(tmp_path / "history.csv", usecols=["value_num"]).value_num
    assert numbers.dtype == float and -1.5 in set(numbers)
    text = (tmp_path / "history.jsonl").read_bytes()
    assert text.isascii()
    assert [json.loads(line)["value_text"] for line in text.splitlines()] == [
        r.value_text for r in rows
    ]
    table = pq.read_table(tmp_path / "history.parquet")
    assert table.column("target_id").to_pylist() == [r.target_id for r in rows]
    assert set(table.schema.metadata) == {b"pandas"}
    assert "touch" not in table.schema.metadata[b"pandas"].decode()


@pytest.mark.slow
def test_plot_csv_reads_back_exactly(hostile_sqlite: toaster.Database, tmp_path: Path) -> None:
    """The plot CSV: text cells neutralised as in exports, pandas reads the ids back after
    stripping the leading ', the negative numbers stay numbers."""
    pd = pytest.importorskip("pandas")
    result = plot_facts(hostile_sqlite, tmp_path / "steps.csv", max_facts=0)
    frame = pd.read_csv(
        result.path, dtype={"fact": str, "agent": str, "value_text": str}, keep_default_na=False
    )
    for column in ("fact", "agent", "value_text"):
        assert not any(v.startswith(FORMULA_START) for v in frame[column]), column
    agents = {csv_untext(v) for v in frame.agent}
    assert agents == {"ROBOT", *HOSTILE}
    assert {csv_untext(v) for v in frame.value_text} >= {*HOSTILE, LONG}
    assert -1.5 in set(pd.to_numeric(frame.value_num[frame.value_num != ""]))


# -- JSON ---------------------------------------------------------------------------------------
def test_json_line_holds_any_text() -> None:
    """A lone surrogate (a Python string can hold one), NaN and a 10 kB id: one ASCII line of
    strict JSON that reads back."""
    obj = {"id": "a\ud800b", "long": LONG, "n": float("nan"), "inf": [float("-inf")]}
    line = json_line(obj)
    assert line.isascii() and "\n" not in line
    assert json.loads(line) == {"id": "a\ud800b", "long": LONG, "n": "NaN", "inf": ["-Infinity"]}
    line.encode("utf-8")


# -- the command line ---------------------------------------------------------------------------
@pytest.mark.slow
def test_cli_listings_quote_ids(hostile_db: toaster.Database) -> None:
    """--csv (formulas neutralised, every id back after the reader strips one '), --json
    (ASCII, exact) and piped tab-separated lines (one line per row, every character visible,
    formulas neutralised)."""
    url = hostile_db.url

    def listing(*flags: str) -> str:
        done = CliRunner().invoke(
            cli, ["--db", str(url), "get-info", "FACT", "CURRENT", "--agent", "ROBOT", *flags]
        )
        assert done.exit_code == 0, done.output
        return done.stdout

    subjects = sorted(r.subject_id for r in toaster.queries.current_facts(hostile_db, "ROBOT"))
    assert {*HOSTILE[:-1], LONG} <= set(subjects)
    records = list(csv.DictReader(io.StringIO(listing("--csv"), newline="")))
    assert sorted(csv_untext(r["subject_id"]) for r in records) == subjects
    assert not any(r["target_id"].startswith(FORMULA_START) for r in records)
    lines = listing("--json").splitlines()
    assert all(line.isascii() for line in lines)
    assert sorted(json.loads(line)["subject_id"] for line in lines) == subjects
    tsv = listing().split("\n")
    assert tsv[-1] == "" and len(tsv) == len(subjects) + 2  # header, rows, final newline
    cells = [line.split("\t") for line in tsv[1:-1]]
    assert {len(c) for c in cells} == {len(tsv[0].split("\t"))}
    shown = [c[tsv[0].split("\t").index("subject")] for c in cells]
    assert sorted(shown) == sorted(visible(csv_text(s)) for s in subjects)
    assert not any(s.startswith(FORMULA_START) for s in shown)


@pytest.mark.slow
def test_terminal_table_shows_ids_as_text(hostile_sqlite: toaster.Database) -> None:
    """On a terminal (a pseudo-terminal here) the table shows rich markup and escape
    sequences of ids as text, with no traceback."""
    main, child = pty.openpty()
    env = {**os.environ, "COLUMNS": "400", "LINES": "100", "TERM": "xterm"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "toaster", "--db", str(hostile_sqlite.url), "get-info", "ENTITY"],
        stdin=child,
        stdout=child,
        stderr=child,
        env=env,
        close_fds=True,
    )
    os.close(child)
    chunks = []
    while True:
        try:
            chunk = os.read(main, 65536)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(main)
    assert proc.wait(60) == 0
    shown = b"".join(chunks).decode("utf-8", "replace")
    assert "Traceback" not in shown
    for name in (
        "[/x][red]r[/red]",
        "\\x1b[31mred\\x1b]0;title\\x07",
        "two\\nlines",
        "\\u202eevil",
    ):
        assert name in shown, name
    assert "\x1b]0;title" not in shown and "\u202e" not in shown


def test_shell_word_runs_nothing(tmp_path: Path) -> None:
    """A shell reads each id quoted by shell_word as one word, the id itself, and runs
    nothing."""
    for name in (*HOSTILE, LONG, ""):
        done = subprocess.run(
            ["sh", "-c", f"printf %s {shell_word(name)}"],
            cwd=tmp_path,
            capture_output=True,
            check=False,
        )
        assert done.returncode == 0 and done.stdout.decode() == name
    assert _created(tmp_path) == []


# -- SQL ----------------------------------------------------------------------------------------
@pytest.mark.slow
def test_agent_views_read_each_hostile_agent(hostile_db: toaster.Database) -> None:
    """Each hostile agent's view (a quoted identifier) holds that agent's fact."""
    agents = {a.id: a for a in toaster.queries.agents(hostile_db)}
    with hostile_db.transaction() as conn:
        cursor = conn.connection.dbapi_connection.cursor()  # type: ignore[union-attr]
        for name in HOSTILE:  # no parameters: the driver reads no placeholder in the name
            cursor.execute(
                "SELECT agent_id, subject_id FROM " + quote_identifier(agents[name].fact_view)
            )
            assert [tuple(r) for r in cursor.fetchall()] == [(name, HELD)]


# -- recordings ---------------------------------------------------------------------------------
PEOPLE = HOSTILE[:8]
THINGS = [*HOSTILE[8:], LONG]


def _frames() -> list[tuple[Any, ...]]:
    """Hostile humans (each with a hostile joint), objects (a 10 kB id among them)
    and a hostile area, over two frames."""
    out = []
    for k in range(2):
        entities: list[Any] = [("ROBOT", "robot", 0.0, 0.0, 0.0, 0.0)]
        for i, name in enumerate(PEOPLE):
            entities.append((name, "human", i, 1.0, 0.0, 0.1 * k))
            entities.append(
                {
                    "id": f"{name}/`head`",
                    "kind": "joint",
                    "x": i,
                    "y": 1.0,
                    "z": 1.6,
                    "yaw": 0.0,
                    "owner": name,
                    "name": "$(head)\n",
                }
            )
        entities += [(name, "object", i, 3.0, 0.7, 0.0) for i, name in enumerate(THINGS)]
        areas = [(f"`touch {MARK}_area` a b", [(0, 0), (1, 0), (1, 1)])] if k == 0 else None
        out.append((T0 + k * S, entities, areas))
    return out


def _check_names(topics: set[str], holders: dict[str, str], frames: set[str]) -> None:
    """Topics are ROS names, each holder's topic follows the rule, frames are one per entity
    and read back to their ids."""
    token = ROS_TOKEN.pattern
    assert all(re.fullmatch(rf"(/{token})+", t) for t in topics), topics
    assert set(holders) == {"ROBOT", *HOSTILE}
    for holder, topic in holders.items():
        assert topic == f"/toaster/beliefs/{ros_name(holder)}"
        assert ros_id(topic.rsplit("/", 1)[1]) == holder
    assert all(re.fullmatch(rf"{token}(/{token})*", f) for f in frames), frames
    expected = {
        "ROBOT/base",
        *(f"{ros_name(p)}/base" for p in PEOPLE),
        *(f"{ros_name(p)}/{ros_name('$(head)' + chr(10))}" for p in PEOPLE),
        *(ros_name(t) for t in THINGS),
    }
    assert frames == expected


_ROSBAG_SCRIPT = r"""
import json, sys
sys.path.append("/usr/lib/python3/dist-packages")
import rosbag, rosgraph.names
bag = rosbag.Bag(sys.argv[1])
info = bag.get_type_and_topic_info()
out = {"topics": sorted(info.topics), "holders": {}, "frames": [], "names": []}
for topic, msg, t in bag.read_messages():
    if topic.startswith("/toaster/beliefs/"):
        out["holders"][msg.holder] = topic
    elif topic == "/tf":
        out["frames"] += [tr.child_frame_id for tr in msg.transforms]
    elif topic == "/pdg/objectList":
        out["names"] += [o.meEntity.id for o in msg.objectList]
out["illegal"] = [name for name in (*out["topics"], *out["frames"])
                  if not rosgraph.names.is_legal_name(name)]
print(json.dumps(out))
"""


@pytest.mark.slow
def test_recordings_open_in_ros_tools(hostile_sqlite: toaster.Database, tmp_path: Path) -> None:
    """A rosbag2 MCAP and a ROS 1 bag of hostile frames and beliefs: rosbags, the mcap library
    (every message decoded), metadata.yaml (a YAML parser) and Debian's rosbag (its Python API
    and ``rosbag info``) open them; topics and TF frames are valid ROS names (rosgraph says so),
    one per holder and entity, read back to their ids by ros_id; the messages keep the exact
    ids."""
    pytest.importorskip("rosbags")
    mcap_reader = pytest.importorskip("mcap.reader")
    mcap_ros2 = pytest.importorskip("mcap_ros2.decoder")
    import yaml  # type: ignore[import-untyped]
    from rosbags.highlevel import AnyReader

    from toaster.outputs.recording import record

    for path in (tmp_path / "rec", tmp_path / "rec.bag"):
        result = record(path, _frames(), db=hostile_sqlite)
        holders: dict[str, str] = {}
        frames: set[str] = set()
        ids: set[str] = set()
        with AnyReader([path]) as reader:
            for conn, _, raw in reader.messages():
                msg = reader.deserialize(raw, conn.msgtype)
                if conn.topic.startswith("/toaster/beliefs/"):
                    holders[msg.holder] = conn.topic
                elif conn.topic == "/tf":
                    frames |= {tr.child_frame_id for tr in msg.transforms}
                elif conn.topic == "/pdg/objectList":
                    items = getattr(msg, "objectList", None) or msg.object_list
                    ids |= {(getattr(o, "meEntity", None) or o.me_entity).id for o in items}
            topics = {c.topic for c in reader.connections}
        _check_names(topics, holders, frames)
        assert ids == set(THINGS)
        if path.suffix == ".bag":
            continue
        meta = yaml.safe_load((path / "metadata.yaml").read_text(encoding="utf-8"))
        listed = {
            t["topic_metadata"]["name"]
            for t in meta["rosbag2_bagfile_information"]["topics_with_message_count"]
        }
        assert listed == topics
        factory, decoders = mcap_ros2.DecoderFactory(), {}
        with result.file.open("rb") as handle:
            for schema, channel, message in mcap_reader.make_reader(handle).iter_messages():
                if schema.id not in decoders:
                    decoders[schema.id] = factory.decoder_for(channel.message_encoding, schema)
                decoders[schema.id](message.data)
    require_system_rosbag()
    bag = tmp_path / "rec.bag"
    done = subprocess.run(
        [SYSTEM_PYTHON, "-c", _ROSBAG_SCRIPT, str(bag)], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    read = json.loads(done.stdout)
    _check_names(set(read["topics"]), read["holders"], set(read["frames"]))
    assert set(read["names"]) == set(THINGS)
    assert read["illegal"] == []  # ROS 1's own check of graph names
    info = subprocess.run(
        ["/usr/bin/rosbag", "info", str(bag)], capture_output=True, text=True, check=False
    )
    assert info.returncode == 0, info.stderr
    assert "/toaster/beliefs/x0" in info.stdout
    assert _created(tmp_path) == []


def test_ros_names_are_one_injective_rule() -> None:
    """ros_name: a token stays itself unless it starts with x0; anything else (and x0...)
    becomes a token that ros_id reads back, so no two ids share a name."""
    ids = [
        *HOSTILE,
        LONG,
        "",
        "alice",
        "PR2_ROBOT",
        "alice_1",
        "alice-1",
        "x0alice_2d1",
        "x0",
        "a__b",
        "a_",
        "3po",
        "é",
        "x0_2d",
    ]
    names = [ros_name(i) for i in ids]
    assert all(ROS_TOKEN.fullmatch(n) for n in names)
    assert [ros_id(n) for n in names] == ids
    assert len(set(names)) == len(ids)
    assert ros_name("PR2_ROBOT") == "PR2_ROBOT" and ros_name("a b") == "x0a_20b"
