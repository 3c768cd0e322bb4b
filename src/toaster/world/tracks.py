"""Recorded tracks: ETH/UCY ``obsmat.txt`` and a generic CSV / JSON-lines format.

Generic format, one sample per row (CSV with a header, or one JSON object per line)::

    t_ns | t_s, id, kind, x, y, z, yaw [, roll, pitch, confidence]

``t_ns`` is integer nanoseconds, ``t_s`` float seconds (exactly one of them). ``kind`` is
human, robot or object (default human); z, yaw, roll, pitch default to 0, confidence to 1.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from toaster.errors import FileFormatError
from toaster.timeutil import NS_PER_S
from toaster.world.state import World

OBSMAT_FRAME_NS = 40_000_000  # 25 fps: 10 frames = 0.4 s


class TrackSource:
    """Replays time-sorted samples into a world: each tick reports samples in (last, t]."""

    def __init__(self, t_ns: np.ndarray, ids: list[str], kinds: dict[str, str],
                 pos: np.ndarray, rpy: np.ndarray, conf: np.ndarray | None = None,
                 name: str = "tracks") -> None:
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

    def setup(self, world: World) -> None:
        """Register every track id (not yet perceived, so not live until its first sample)."""
        for eid, kind in self.kinds.items():
            world.add_entity(eid, kind)

    def advance(self, world: World, t_ns: int) -> None:
        """Report the samples up to ``t_ns``."""
        stop = int(np.searchsorted(self.t, t_ns, side="right"))
        if stop > self._cursor:
            sl = slice(self._cursor, stop)
            world.observe(self.name, self.ids[sl], self.t[sl], self.pos[sl], self.rpy[sl],
                          self.conf[sl])
            self._cursor = stop


def read_obsmat(path: str | Path, prefix: str = "ped", start_ns: int = 0) -> TrackSource:
    """Read an ETH/UCY obsmat.txt (frame ped x z y vx vz vy); yaw follows the velocity."""
    try:
        data = np.loadtxt(path, ndmin=2)
    except (OSError, ValueError) as exc:
        msg = f"cannot read obsmat {str(path)!r} ({exc}): expected 8 numeric columns"
        raise FileFormatError(msg) from None
    if data.shape[1] != 8:
        msg = f"{str(path)!r} has {data.shape[1]} columns: obsmat has 8 (frame ped x z y vx vz vy)"
        raise FileFormatError(msg)
    frame, ped = data[:, 0].astype(np.int64), data[:, 1].astype(np.int64)
    order = np.lexsort((frame, ped))
    frame, ped, data = frame[order], ped[order], data[order]
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
    t = start_ns + frame * OBSMAT_FRAME_NS
    return TrackSource(t, ids, dict.fromkeys(ids, "human"), pos, rpy, name="obsmat")


def _rows(path: Path) -> list[dict]:
    try:
        with path.open(encoding="utf-8") as fh:
            if path.suffix in (".jsonl", ".ndjson"):
                return [json.loads(line) for line in fh if line.strip()]
            return list(csv.DictReader(fh))
    except (OSError, json.JSONDecodeError, csv.Error) as exc:
        msg = f"cannot read tracks {path.name!r} ({exc}): one sample per line is expected"
        raise FileFormatError(msg) from None


def read_tracks(path: str | Path) -> TrackSource:
    """Read a generic CSV (.csv) or JSON-lines (.jsonl) track file."""
    path = Path(path)
    rows = _rows(path)
    if not rows:
        msg = f"{path.name!r} holds no samples"
        raise FileFormatError(msg)
    n = len(rows)
    t = np.zeros(n, np.int64)
    pos, rpy, conf = np.zeros((n, 3)), np.zeros((n, 3)), np.ones(n)
    ids: list[str] = []
    kinds: dict[str, str] = {}
    for i, row in enumerate(rows):
        where = f"{path.name} sample {i + 1}"
        if ("t_ns" in row) == ("t_s" in row):
            msg = f"{where}: give exactly one time column, t_ns (integer ns) or t_s (seconds)"
            raise FileFormatError(msg)
        try:
            if "t_ns" in row:
                t[i] = int(str(row["t_ns"]).strip())
            else:
                t[i] = round(float(row["t_s"]) * NS_PER_S)
            pos[i] = [float(row["x"]), float(row["y"]), float(row.get("z") or 0)]
            rpy[i] = [float(row.get("roll") or 0), float(row.get("pitch") or 0),
                      float(row.get("yaw") or 0)]
            conf[i] = float(row.get("confidence") or 1)
        except (KeyError, ValueError, TypeError) as exc:
            msg = (f"{where}: bad or missing value ({exc}); t_ns must be an integer, "
                   "x, y, z in metres and yaw in radians")
            raise FileFormatError(msg) from None
        if not all(math.isfinite(v) for v in (*pos[i], *rpy[i])):
            msg = f"{where}: non-finite pose"
            raise FileFormatError(msg)
        eid = str(row.get("id") or "")
        if not eid:
            msg = f"{where}: missing id"
            raise FileFormatError(msg)
        kind = str(row.get("kind") or "human").lower()
        if kind not in ("human", "robot", "object"):
            msg = f"{where}: kind {kind!r} must be human, robot or object"
            raise FileFormatError(msg)
        ids.append(eid)
        kinds.setdefault(eid, kind)
    return TrackSource(t, ids, kinds, pos, rpy, conf, name=path.stem)
