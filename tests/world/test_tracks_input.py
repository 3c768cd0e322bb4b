"""Tracks input: the obsmat frame rate (checked against the annotated velocities) and bad values
refused with their line number before anything is written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import toaster
from tests.conftest import count, shared_data
from toaster.cli import cli
from toaster.errors import FileFormatError, InvalidInputError
from toaster.producers import Runner, load_session
from toaster.world import read_obsmat, read_tracks

S = 1_000_000_000


def zara01() -> Path:
    return shared_data("eth-ucy-opentraj", "UCY", "zara01", "obsmat.txt")


def replay(session, until_ns: int) -> list[dict]:
    """Every tick's snapshots (no store) up to ``until_ns`` of input."""
    runner = Runner(session.world, session.sources, session.producers, agent_id=session.self_id)
    seen: list[dict] = []
    runner.run(
        session.start_ns,
        min(session.end_ns, session.start_ns + until_ns),
        session.rate_hz,
        on_tick=lambda t: seen.append(runner.diff._last.copy()),
    )
    return seen


def one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text
    return text


@pytest.mark.shared_data
def test_doubled_frames_at_50_fps_give_the_same_times_and_facts(tmp_path: Path) -> None:
    original = zara01()
    data = np.loadtxt(original, ndmin=2)
    data[:, 0] *= 2
    doubled = tmp_path / "obsmat.txt"
    np.savetxt(doubled, data, fmt="%.7e")
    a, b = read_obsmat(original), read_obsmat(doubled, fps=50)
    assert np.array_equal(a.t, b.t)
    assert a.ids == b.ids
    assert np.allclose(a.pos, b.pos)
    assert a.sample_hz == b.sample_hz == 2.5
    at25, at50 = load_session(original), load_session(doubled, fps=50)
    assert (at25.start_ns, at25.end_ns, at25.rate_hz) == (at50.start_ns, at50.end_ns, 2.5)
    snaps = replay(at25, 40 * S)
    assert snaps == replay(at50, 40 * S)
    assert any(snaps)
    with pytest.raises(FileFormatError, match="imply about 50 fps") as info:
        read_obsmat(doubled)
    assert "give --fps 50" in one_line(info)


@pytest.mark.shared_data
@pytest.mark.parametrize("fps", [50, 12.5, 100])
def test_mismatching_fps_is_refused(fps: float) -> None:
    with pytest.raises(
        FileFormatError,
        match=rf"--fps {fps:g} does not fit zara01/obsmat.txt: "
        r"its annotated velocities imply about 25 fps \(positions move 0.48 m "
        r"per 10 frames at 1.20 m/s\); give --fps 25",
    ) as info:
        load_session(zara01(), fps=fps)
    one_line(info)


@pytest.mark.shared_data
def test_both_shared_files_fit_25_fps() -> None:
    for scene in (("ETH", "seq_hotel"), ("UCY", "zara01")):
        source = read_obsmat(shared_data("eth-ucy-opentraj", *scene, "obsmat.txt"), fps=25)
        assert source.sample_hz == 2.5
        assert source.t[0] == 40_000_000  # frame 1


@pytest.mark.parametrize("fps", [0, -25, float("nan"), float("inf")])
def test_fps_must_be_positive(tmp_path: Path, fps: float) -> None:
    path = tmp_path / "obsmat.txt"
    path.write_text("1 1 0 0 0 0 0 0\n")
    with pytest.raises(InvalidInputError, match="must be a positive number of frames"):
        read_obsmat(path, fps=fps)


def test_fps_only_for_obsmat(tmp_path: Path) -> None:
    csv = tmp_path / "t.csv"
    csv.write_text("t_s,id,x,y\n0,bob,0,0\n")
    with pytest.raises(InvalidInputError, match="--fps is for obsmat .txt recordings") as info:
        load_session(csv, fps=25)
    one_line(info)


GOOD = ["1 1 -2.8 0 18.9 0 0 -1.3", "11 1 -2.8 0 18.4 0 0 -1.3", "1 2 3.0 0 4.0 1.0 0 0"]


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("21 1 nan 0 17.9 0 0 -1.3", "line 4: pos_x is nan, not a finite number"),
        ("21 1 -2.8 0 inf 0 0 -1.3", "line 4: pos_y is inf, not a finite number"),
        ("21 1 -2.8 0 17.9 0 0 -inf", "line 4: v_y is -inf, not a finite number"),
        ("nan 1 -2.8 0 17.9 0 0 -1.3", "line 4: frame is nan, not a finite number"),
        ("-10 1 -2.8 0 17.9 0 0 -1.3", "line 4: frame -10 is not a frame number"),
        ("20.5 1 -2.8 0 17.9 0 0 -1.3", "line 4: frame 20.5 is not a frame number"),
        ("21 -1 -2.8 0 17.9 0 0 -1.3", "line 4: person id -1 is not an id"),
        ("21 1.5 -2.8 0 17.9 0 0 -1.3", "line 4: person id 1.5 is not an id"),
        ("21 nan -2.8 0 17.9 0 0 -1.3", "line 4: ped is nan, not a finite number"),
        ("21 1 abc 0 17.9 0 0 -1.3", "line 4: pos_x 'abc' is not a number"),
        ("21 1 -2.8 0 17.9 0 0", "line 4 has 7 columns: obsmat has 8"),
    ],
)
def test_bad_obsmat_values_name_the_line(tmp_path: Path, line: str, message: str) -> None:
    path = tmp_path / "obsmat.txt"
    path.write_text("\n".join([GOOD[0], "", GOOD[1], line, GOOD[2]]) + "\n")
    with pytest.raises(FileFormatError, match=rf"^{tmp_path.name}/obsmat.txt {message}") as info:
        read_obsmat(path)
    assert "fix" in one_line(info) or "columns" in one_line(info)


@pytest.mark.parametrize(
    ("suffix", "row", "message"),
    [
        (".csv", "1.0,bob,nan,0,0", "line 3: x is 'nan', not a finite number"),
        (".csv", "1.0,bob,0,0,inf", "line 3: yaw is 'inf', not a finite number"),
        (".csv", "nan,bob,0,0,0", "line 3: t_s is 'nan', not a finite number"),
        (".csv", "1.0,bob,0,x,0", "line 3: y 'x' is not a number"),
        (".csv", "1.0,bob,0,0,0,NaN", "line 3: confidence is 'NaN', not a finite number"),
        (".csv", "1.0,bob,0,0,0,1.5", "line 3: confidence 1.5 must be between 0 and 1"),
        (".jsonl", '{"t_s": 1, "id": "bob", "x": NaN, "y": 0}', "line 3: x is nan, not a finite"),
        (
            ".jsonl",
            '{"t_s": 1, "id": "bob", "x": 0, "y": 0, "yaw": -Infinity}',
            "line 3: yaw is -inf, not a finite",
        ),
        (
            ".jsonl",
            '{"t_ns": 1.5, "id": "bob", "x": 0, "y": 0}',
            "line 3: t_ns 1.5 is not an integer",
        ),
        (
            ".jsonl",
            '{"t_s": 1, "id": "bob", "x": 0, "y": 0, "confidence": NaN}',
            "line 3: confidence is nan, not a finite",
        ),
        (".jsonl", "[1, 2]", "line 3: list instead of a JSON object"),
        (".jsonl", '{"t_s": 1,', "line 3: not JSON"),
    ],
)
def test_bad_track_values_name_the_line(
    tmp_path: Path, suffix: str, row: str, message: str
) -> None:
    path = tmp_path / f"tracks{suffix}"
    if suffix == ".csv":
        path.write_text(f"t_s,id,x,y,yaw,confidence\n0.0,bob,0,0,0,1\n{row}\n")
    else:
        path.write_text(f'{{"t_s": 0, "id": "bob", "x": 0, "y": 0}}\n\n{row}\n')
    with pytest.raises(FileFormatError, match=rf"^tracks{suffix} {message}") as info:
        read_tracks(path)
    one_line(info)


def test_good_tracks_still_read(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("t_ns,id,kind,x,y,z,yaw,confidence\n5,bob,human,1,2,,0.5,0.9\n")
    source = read_tracks(path)
    assert source.t.tolist() == [5]
    assert source.pos.tolist() == [[1.0, 2.0, 0.0]]
    assert source.conf.tolist() == [0.9]


def test_cli_refuses_a_bad_file_before_writing(db_url: str, tmp_path: Path) -> None:
    path = tmp_path / "bad.txt"
    path.write_text("\n".join([*GOOD, "21 1 -2.8 0 nan 0 0 -1.3"]) + "\n")
    done = CliRunner().invoke(cli, ["run", str(path), "--db", db_url])
    assert done.exit_code == 1
    lines = done.output.strip().splitlines()
    assert lines == [
        f"Error: {tmp_path.name}/bad.txt line 4: pos_y is nan, not a finite number: "
        "fix or delete the line"
    ]
    db = toaster.connect(db_url)
    try:
        assert count(db, "SELECT count(*) FROM facts") == 0
        assert count(db, "SELECT count(*) FROM entities") == 0
        assert count(db, "SELECT count(*) FROM agents") == 0
    finally:
        db.close()
