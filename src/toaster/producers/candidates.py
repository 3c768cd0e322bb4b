"""Candidate pairs for the spatial producer: which boxes are near enough to be tested at all.

Every function here returns a superset of the pairs that can satisfy a relation; the producer
(``spatial.py``) then runs its exact tests on those pairs only, so its facts are those of the
all-pairs computation (``tests/producers/test_spatial_index.py`` compares them on random scenes).

- :class:`BoxIndex`: a per-tick shapely 2 ``STRtree`` of the boxes' 2D bounding boxes (widened by
  :func:`margin`), queried with the supports' and containers' own boxes (IsOn, IsIn) and with
  squares of a relation's distance around an agent (arm reach, view range).
  Chosen over a uniform numpy grid, which measured no faster in the whole tick at 1,000 boxes
  and slower at 100 (with 1, 2 or 4 m cells), and whose cell size would have to suit every
  scene (figures in docs/producers.md, "Spatial relations").
- :func:`window_pairs`: sort and sweep on x within groups (IsNextTo: objects of one place, whose
  footprints it compares as circles; the same window as before the index, now in one pass).
- :func:`azimuth_pairs`: for the rays of visibility, the occluders whose footprint circle, seen
  from the ray's eye, spans the ray's azimuth (rays sorted by agent and azimuth, one
  ``searchsorted`` per occluder): a few occluders per ray instead of all in the view range.
"""

from __future__ import annotations

import numpy as np
import shapely

#: Key stride between owners in :func:`azimuth_pairs` (> 4π: each ray appears at a and a + 2π).
_TURN = 16.0


def expand(start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ranges [start, end) unrolled: (index of the range, position) of every element, in order."""
    count = np.maximum(end - start, 0)
    owner = np.repeat(np.arange(len(start)), count)
    pos = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count - start, count)
    return owner, pos


def margin(centre: np.ndarray) -> float:
    """Widening of every bounding box: float rounding (float32 rays) never loses a pair."""
    scale = float(np.abs(centre[np.isfinite(centre)]).max(initial=0.0))
    return 1e-3 + 1e-6 * scale


def footprint(
    centre: np.ndarray, half: np.ndarray, cos: np.ndarray, sin: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """2D bounding boxes (lo, hi), each (n, 2), of boxes turned by their yaw."""
    c, s = np.abs(cos), np.abs(sin)
    ext = np.stack([c * half[:, 0] + s * half[:, 1], s * half[:, 0] + c * half[:, 1]], axis=1)
    return centre[:, :2] - ext, centre[:, :2] + ext


class BoxIndex:
    """2D boxes (lo, hi) in an STRtree, each widened by ``pad``; non-finite boxes left out."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, pad: float) -> None:
        ok = np.isfinite(lo).all(axis=1) & np.isfinite(hi).all(axis=1)
        self.pad = pad
        self.ids = np.flatnonzero(ok)
        self.slot = np.full(len(lo), -1)
        self.slot[self.ids] = np.arange(self.ids.size)
        lo, hi = lo[ok] - pad, hi[ok] + pad
        self.geoms = shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1])
        self.tree = shapely.STRtree(self.geoms)

    def query(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(query row, box) of every query box (lo, hi) overlapping an indexed box."""
        ok = np.flatnonzero(np.isfinite(lo).all(axis=1) & np.isfinite(hi).all(axis=1))
        geoms = shapely.box(lo[ok, 0], lo[ok, 1], hi[ok, 0], hi[ok, 1])
        q, t = self.tree.query(geoms)
        return ok[q], self.ids[t]

    def query_boxes(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(box of ``boxes``, other box) of indexed boxes overlapping each other (self included)."""
        boxes = boxes[self.slot[boxes] >= 0]
        q, t = self.tree.query(self.geoms[self.slot[boxes]])
        return boxes[q], self.ids[t]


def window_pairs(group: np.ndarray, x: np.ndarray, limit: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pairs i < j of one group with x[j] <= limit[i] (>= x[i]), elements sorted by (group, x).

    Exact: a sweep on keys (group rank, x) gives a superset, filtered with the test itself.
    """
    n = len(x)
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    rank = np.cumsum(np.r_[0, group[1:] != group[:-1]])
    lo = x.min()
    span = (x.max() - lo) + (limit - x).max() + 1.0
    key = rank * span + (x - lo)
    hi = np.searchsorted(key, rank * span + (limit - lo), side="right")
    i, j = expand(np.arange(1, n + 1), hi)
    keep = (group[j] == group[i]) & (x[j] <= limit[i])
    return i[keep], j[keep]


def azimuth_pairs(
    ray_owner: np.ndarray,
    ray_angle: np.ndarray,
    occ_owner: np.ndarray,
    occ_angle: np.ndarray,
    occ_half: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(ray, occluder) pairs of one owner whose angles overlap.

    Angles in [-π, π] (``arctan2``); an occluder covers [angle - half, angle + half], half at
    most π/2, or every ray of its owner when half is infinite.
    """
    order = np.lexsort((ray_angle, ray_owner))
    owner = ray_owner[order]
    whole = np.isinf(occ_half)
    w = np.flatnonzero(whole)
    wi, wpos = expand(
        np.searchsorted(owner, occ_owner[w], "left"), np.searchsorted(owner, occ_owner[w], "right")
    )
    base = owner * _TURN + (ray_angle[order] + np.pi)
    key = np.r_[base, base + 2 * np.pi]
    by_key = np.argsort(key, kind="stable")
    key, ids = key[by_key], np.r_[order, order][by_key]
    p = np.flatnonzero(~whole)
    tol = 1e-9
    lo = occ_angle[p] + np.pi - occ_half[p] - tol
    hi = occ_angle[p] + np.pi + occ_half[p] + tol
    turn = np.where(lo < 0.0, 2 * np.pi, 0.0)
    own = occ_owner[p] * _TURN
    pi, pos = expand(
        np.searchsorted(key, own + (lo + turn), "left"),
        np.searchsorted(key, own + (hi + turn), "right"),
    )
    return np.r_[order[wpos], ids[pos]], np.r_[w[wi], p[pi]]
