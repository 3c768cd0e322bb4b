"""Recorded tracks: ETH/UCY ``obsmat.txt`` and a generic CSV / JSON-lines format.

Generic format, one sample per row (CSV with a header, or one JSON object per line)::

    t_ns | t_s, id, kind, x, y, z, yaw [, roll, pitch, confidence]

``t_ns`` is integer nanoseconds, ``t_s`` float seconds (exactly one of them). ``kind`` is
human, robot or object (default human); z, yaw, roll, pitch default to 0, confidence to 1.
The orientation may instead be a quaternion ``qx, qy, qz, qw`` (as ROS gives it).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from toaster.errors import FileFormatError, InvalidInputError
from toaster.model import MAX_COORD, check_id, shown
from toaster.timeutil import MAX_NS, MAX_RATE_HZ, MIN_RATE_HZ, NS_PER_S, check_ns
from toaster.world.geometry import check_quat, quats_to_rpy
from toaster.world.state import World

OBSMAT_FPS = 25.0  # ETH/UCY videos: 25 fps, annotated every 10 frames (0.4 s, 2.5 Hz)
OBSMAT_FRAME_NS = 40_000_000  # one frame at OBSMAT_FPS
OBSMAT_COLUMNS = ("frame", "ped", "pos_x", "pos_z", "pos_y", "v_x", "v_z", "v_y")
MAX_INT_ID = 2**53  # frame numbers and person ids beyond are not exact in a float column
FPS_TOLERANCE = 1.5  # refuse an fps more than this factor away from what the velocities imply


class TrackSource:
    """Replays time-sorted samples into a world: each tick reports samples in (last, t]."""

    def __init__(
        self,
        t_ns: np.ndarray,
        ids: list[str],
        kinds: dict[str, str],
        pos: np.ndarray,
        rpy: np.ndarray,
        conf: np.ndarray | None = None,
        name: str = "tracks",
    ) -> None:
        order = np.argsort(t_ns, kind="stable")
        self.t = np.asarray(t_ns, np.int64)[order]
        self.ids = [ids[i] for i in order]
        self.pos, self.rpy = pos[order], rpy[order]
        self.conf = np.ones(len(order)) if conf is None else conf[order]
        self.kinds = kinds
        self.name = name
        self._cursor = 0
        self.start_ns = int(self.t[0]) if len(self.t) else 0
        self.end_ns = int(self.t[-1]) if len(self.t) else 0
        self.sample_hz: float | None = None  # the annotation rate, when the file tells it
        steps = np.diff(np.unique(self.t))  # else the median step between sample times
        if len(steps):
            self.sample_hz = _clamp_rate(NS_PER_S / float(np.median(steps)))

    def sample_times(self) -> np.ndarray:
        """Every distinct sample time."""
        return np.unique(self.t)

    def setup(self, world: World) -> None:
        """Register every track id (not yet perceived, so not live until its first sample)."""
        for eid, kind in self.kinds.items():
            world.add_entity(eid, kind)

    def advance(self, world: World, t_ns: int) -> None:
        """Report the samples up to ``t_ns``."""
        stop = int(np.searchsorted(self.t, t_ns, side="right"))
        if stop > self._cursor:
            sl = slice(self._cursor, stop)
            world.observe(
                self.name, self.ids[sl], self.t[sl], self.pos[sl], self.rpy[sl], self.conf[sl]
            )
            self._cursor = stop


def _clamp_rate(hz: float) -> float:
    """A sample rate within what a run may tick at (MIN_RATE_HZ..MAX_RATE_HZ)."""
    return min(max(hz, MIN_RATE_HZ), MAX_RATE_HZ)


def _label(path: Path) -> str:
    """``seq_hotel/obsmat.txt``: the file with its folder (obsmat files all share one name)."""
    return f"{path.parent.name}/{path.name}" if path.parent.name else path.name


def _obsmat_table(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The numbers of an obsmat file (n × 8) and the line number of each row."""
    label = _label(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        msg = f"cannot read obsmat {label!r} ({exc}): expected 8 numeric columns"
        raise FileFormatError(msg) from None
    numbers, rows = [], []
    for n, line in enumerate(text.splitlines(), 1):
        fields = line.split("#", 1)[0].split()
        if fields:
            numbers.append(n)
            rows.append(fields)
            if len(fields) != len(OBSMAT_COLUMNS):
                msg = (
                    f"{label} line {n} has {len(fields)} columns: obsmat has 8 "
                    "(frame ped x z y vx vz vy)"
                )
                raise FileFormatError(msg)
    if not rows:
        msg = f"{label} holds no samples: obsmat has one row per person and frame"
        raise FileFormatError(msg)
    try:
        data = np.array(rows, dtype=float)
    except ValueError:
        for n, fields in zip(numbers, rows, strict=True):
            for column, word in zip(OBSMAT_COLUMNS, fields, strict=True):
                try:
                    float(word)
                except ValueError:
                    msg = (
                        f"{label} line {n}: {column} {word!r} is not a number; obsmat rows "
                        "are 8 numbers (frame ped x z y vx vz vy): fix or delete the line"
                    )
                    raise FileFormatError(msg) from None
        raise  # pragma: no cover - numpy and float() agree on what a number is
    return data, np.asarray(numbers, np.int64)


def _check_obsmat(label: str, data: np.ndarray, lines: np.ndarray) -> None:
    """Refuse non-finite numbers and frames / person ids that are not non-negative integers."""
    finite = np.isfinite(data)
    ints = data[:, :2]
    bad_int = (ints < 0) | (ints != np.floor(ints)) | (ints > MAX_INT_ID)
    big = np.abs(np.where(finite[:, 2:], data[:, 2:], 0)) > MAX_COORD
    bad = ~finite.all(axis=1) | bad_int.any(axis=1) | big.any(axis=1)
    if not bad.any():
        return
    i = int(np.argmax(bad))
    where = f"{label} line {lines[i]}"
    if big[i].any():
        column = OBSMAT_COLUMNS[2 + int(np.argmax(big[i]))]
        value = data[i, OBSMAT_COLUMNS.index(column)]
        msg = f"{where}: {column} {value:g} is beyond ±{MAX_COORD:g} m: fix or delete the line"
    elif not finite[i].all():
        column = OBSMAT_COLUMNS[int(np.argmin(finite[i]))]
        value = data[i, OBSMAT_COLUMNS.index(column)]
        msg = f"{where}: {column} is {value}, not a finite number: fix or delete the line"
    elif bad_int[i, 0]:
        msg = (
            f"{where}: frame {data[i, 0]:g} is not a frame number (frames are non-negative "
            "integers; columns are frame ped x z y vx vz vy): fix or delete the line"
        )
    else:
        msg = (
            f"{where}: person id {data[i, 1]:g} is not an id (ids are non-negative integers; "
            "columns are frame ped x z y vx vz vy): fix or delete the line"
        )
    raise FileFormatError(msg)


def _check_fps(
    label: str, fps: float, frame: np.ndarray, ped: np.ndarray, data: np.ndarray
) -> float | None:
    """The median frame step between a person's rows; refuse an fps the velocities contradict.

    Rows are sorted by person then frame. Over consecutive rows of a person that walks
    (mean annotated speed > 0.2 m/s), ``speed × frames / distance`` estimates the frame rate.
    """
    same = ped[1:] == ped[:-1]
    steps = (frame[1:] - frame[:-1])[same].astype(float)
    if not len(steps):
        return None
    step = float(np.median(steps))
    moved = np.hypot(data[1:, 2] - data[:-1, 2], data[1:, 4] - data[:-1, 4])[same]
    speed = np.hypot(data[:, 5], data[:, 7])
    speed = ((speed[1:] + speed[:-1]) / 2)[same]
    use = (speed > 0.2) & (moved > 0) & (steps > 0)
    if use.sum() < 10:
        return step
    fit = float(np.median(speed[use] * steps[use] / moved[use]))
    if not 1 / FPS_TOLERANCE <= fps / fit <= FPS_TOLERANCE:
        per_step = float(np.median(moved[use] * step / steps[use]))
        at = float(np.median(speed[use]))
        guess = f"{round(fit):d}" if fit >= 10 else f"{fit:.2g}"
        msg = (
            f"--fps {fps:g} does not fit {label}: its annotated velocities imply about "
            f"{guess} fps (positions move {per_step:.2f} m per {step:g} frames at "
            f"{at:.2f} m/s); give --fps {guess}"
        )
        raise FileFormatError(msg)
    return step


def read_obsmat(
    path: str | Path, prefix: str = "ped", start_ns: int = 0, fps: float = OBSMAT_FPS
) -> TrackSource:
    """Read an ETH/UCY obsmat.txt (frame ped x z y vx vz vy); yaw follows the velocity.

    ``fps`` is the video frame rate the frame numbers count (ETH/UCY: 25). It is checked
    against the file: the annotated velocities must agree with the positions' steps. Bad rows
    (non-finite numbers, negative or fractional frames or ids) are refused with their line.
    """
    try:
        rate = math.nan if isinstance(fps, bool) else float(fps)
    except (TypeError, ValueError):
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        msg = f"--fps {fps!r} must be a positive number of frames per second (ETH/UCY: 25)"
        raise InvalidInputError(msg)
    path = Path(path)
    label = _label(path)
    data, lines = _obsmat_table(path)
    _check_obsmat(label, data, lines)
    frame, ped = data[:, 0].astype(np.int64), data[:, 1].astype(np.int64)
    order = np.lexsort((frame, ped))
    frame, ped, data = frame[order], ped[order], data[order]
    step = _check_fps(label, rate, frame, ped, data)
    yaw = np.arctan2(data[:, 7], data[:, 5])
    still = np.hypot(data[:, 5], data[:, 7]) == 0
    idx = np.where(~still, np.arange(len(yaw)), 0)
    first = np.r_[True, ped[1:] != ped[:-1]]
    idx = np.where(first & still, np.arange(len(yaw)), idx)
    np.maximum.accumulate(idx, out=idx)
    yaw = yaw[idx]
    ids = [f"{prefix}{p}" for p in ped.tolist()]
    pos = np.column_stack([data[:, 2], data[:, 4], np.zeros(len(data))])
    rpy = np.column_stack([np.zeros(len(data)), np.zeros(len(data)), yaw])
    last = float(frame.max()) * (NS_PER_S / rate) + start_ns
    if not (start_ns >= 0 and last <= MAX_NS - NS_PER_S):
        msg = (
            f"{label}: frame {int(frame.max())} at {fps!r} fps is beyond the year 2262 "
            "(times are 64-bit nanoseconds): fix the frame numbers or --fps"
        )
        raise FileFormatError(msg)
    t = start_ns + np.rint(frame * (NS_PER_S / rate)).astype(np.int64)
    source = TrackSource(t, ids, dict.fromkeys(ids, "human"), pos, rpy, name="obsmat")
    if step:
        source.sample_hz = _clamp_rate(rate / step)
    return source


def _rows(path: Path) -> list[tuple[int, dict]]:
    """The samples of a CSV / JSON-lines file, each with its line number."""
    out: list[tuple[int, dict]] = []
    try:
        with path.open(encoding="utf-8", newline="") as fh:
            if path.suffix in (".jsonl", ".ndjson"):
                for n, line in enumerate(fh, 1):
                    if not line.strip():
                        continue
                    try:
                        row = json.loads(line)
                    except json.JSONDecodeError as exc:
                        msg = (
                            f"{path.name} line {n}: not JSON ({exc.msg}); one JSON object "
                            "per line is expected"
                        )
                        raise FileFormatError(msg) from None
                    if not isinstance(row, dict):
                        msg = (
                            f"{path.name} line {n}: {type(row).__name__} instead of a JSON "
                            'object such as {"t_s": 0.5, "id": "bob", "x": 1, "y": 2}'
                        )
                        raise FileFormatError(msg)
                    out.append((n, row))
                return out
            reader = csv.DictReader(fh)
            out.extend((reader.line_num, row) for row in reader)
            return out
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        msg = f"cannot read tracks {path.name!r} ({exc}): one sample per line is expected"
        raise FileFormatError(msg) from None


def _number(
    row: dict, key: str, default: float | None, where: str, unit: str, limit: float = MAX_COORD
) -> float:
    """One finite number of a sample within ±``limit`` (``default`` when absent or empty;
    None: required)."""
    raw = row.get(key)
    if raw is None or (isinstance(raw, str) and not raw.strip()):
        if default is None:
            msg = f"{where}: missing {key} ({unit})"
            raise FileFormatError(msg)
        return default
    try:
        if isinstance(raw, bool):
            raise TypeError
        value = float(raw)
    except (TypeError, ValueError, OverflowError):
        msg = f"{where}: {key} {shown(raw)} is not a number ({unit}): fix or delete the line"
        raise FileFormatError(msg) from None
    if not math.isfinite(value):
        msg = (
            f"{where}: {key} is {shown(raw)}, not a finite number ({unit}): fix or delete the line"
        )
        raise FileFormatError(msg)
    if abs(value) > limit:
        msg = f"{where}: {key} {shown(raw)} is beyond ±{limit:g} ({unit}): fix or delete the line"
        raise FileFormatError(msg)
    return value


def _time_ns(row: dict, where: str) -> int:
    """The sample time: integer ``t_ns`` or finite ``t_s`` (exactly one)."""
    if ("t_ns" in row) == ("t_s" in row):
        msg = f"{where}: give exactly one time column, t_ns (integer ns) or t_s (seconds)"
        raise FileFormatError(msg)
    try:
        if "t_s" in row:
            return check_ns(
                round(_number(row, "t_s", None, where, "seconds", MAX_NS / NS_PER_S) * NS_PER_S),
                f"{where}: t_s =",
            )
        raw = row["t_ns"]
        text = str(raw).strip() if isinstance(raw, int | str) and not isinstance(raw, bool) else ""
        if not text.lstrip("+-").isdigit() or len(text) > 30:
            msg = (
                f"{where}: t_ns {shown(raw)} is not an integer number of nanoseconds "
                "(use t_s for seconds): fix or delete the line"
            )
            raise FileFormatError(msg)
        return check_ns(int(text), f"{where}: t_ns")
    except InvalidInputError as exc:
        if isinstance(exc, FileFormatError):
            raise
        raise FileFormatError(str(exc)) from None


def read_tracks(path: str | Path) -> TrackSource:
    """Read a generic CSV (.csv) or JSON-lines (.jsonl) track file.

    Bad samples (missing or non-numeric values, NaN or infinite poses, confidence outside
    [0, 1]) are refused with their line number.
    """
    path = Path(path)
    rows = _rows(path)
    if not rows:
        msg = f"{path.name!r} holds no samples"
        raise FileFormatError(msg)
    n = len(rows)
    t = np.zeros(n, np.int64)
    pos, rpy, conf = np.zeros((n, 3)), np.zeros((n, 3)), np.ones(n)
    quats = np.full((n, 4), np.nan)  # rows given as quaternions, turned into angles at once
    ids: list[str] = []
    kinds: dict[str, str] = {}
    for i, (line, row) in enumerate(rows):
        where = f"{path.name} line {line}"
        t[i] = _time_ns(row, where)
        pos[i] = [
            _number(row, key, None if key != "z" else 0.0, where, "metres")
            for key in ("x", "y", "z")
        ]
        if "qw" in row:  # a quaternion, as ROS gives orientations
            q = [
                _number(row, key, None, where, "a quaternion component")
                for key in ("qx", "qy", "qz", "qw")
            ]
            try:
                quats[i] = check_quat(q)
            except ValueError as exc:
                msg = f"{where}: {exc}"
                raise FileFormatError(msg) from None
        else:
            rpy[i] = [_number(row, key, 0.0, where, "radians") for key in ("roll", "pitch", "yaw")]
        conf[i] = _number(row, "confidence", 1.0, where, "between 0 and 1")
        if not 0 <= conf[i] <= 1:
            msg = f"{where}: confidence {conf[i]:g} must be between 0 and 1: fix the line"
            raise FileFormatError(msg)
        raw_id = row.get("id")
        if raw_id in (None, ""):
            msg = f"{where}: missing id"
            raise FileFormatError(msg)
        if isinstance(raw_id, int) and not isinstance(raw_id, bool):
            raw_id = str(raw_id)
        try:
            eid = check_id(raw_id, "id")
        except InvalidInputError as exc:
            msg = f"{where}: {exc}"
            raise FileFormatError(msg) from None
        kind = row.get("kind") or "human"
        kind = kind.lower() if isinstance(kind, str) else kind
        if kind not in ("human", "robot", "object"):
            msg = f"{where}: kind {shown(kind)} must be human, robot or object"
            raise FileFormatError(msg)
        ids.append(eid)
        kinds.setdefault(eid, kind)
    turned = ~np.isnan(quats[:, 3])
    rpy[turned] = quats_to_rpy(quats[turned])
    return TrackSource(t, ids, kinds, pos, rpy, conf, name=path.stem)
