"""Where a sampled path crosses the planes of many stations: every station of one cycle at once (ISO 9283 8.2).

A station's plane through ``s`` with unit normal ``n`` cuts the polyline of the attained samples ``p_k`` where the
signed distance

.. math:: \\delta_k = (p_k - s) \\cdot n

changes sign (``signbit`` differs between k and k + 1; the crossing p_k + f (p_{k+1} - p_k) with
f = δ_k / (δ_k - δ_{k+1})) or is zero (f = 0); of several crossings the one nearest the station is kept, ties to a
zero, then to the earlier sample. A long path's cycle has about 10^4 samples and 10^2 stations, and each plane is
crossed at one or two places: the samples are cut into blocks of :data:`BLOCK_SAMPLES`, and a plane is tested
sample by sample only in the blocks whose bounding box it cuts. The box test is exact, not approximate: each term
(p_a - s_a) n_a is a monotone function of p_a in floating point (a rounded subtraction and product), and so is the
rounded sum of the terms, so the δ_k of a block's samples lie between the same sums taken at the box's corners.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BLOCK_SAMPLES", "plane_crossings"]

#: Samples per block of the box test (a plane's candidates are read in blocks of this many samples).
BLOCK_SAMPLES = 64
#: Block-station box tests made at once (about 60 bytes each): a long single path is cut station chunk by chunk.
_BOX_TESTS = 1 << 20


def _signed(points: np.ndarray, stations: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """δ = (p - s) · n term by term, summed axis after axis (the order :func:`plane_crossings` relies on)."""
    total = (points[..., 0] - stations[..., 0]) * normals[..., 0]
    for axis in range(1, points.shape[-1]):
        total = total + (points[..., axis] - stations[..., axis]) * normals[..., axis]
    return total


def plane_crossings(
    path: np.ndarray, stations: np.ndarray, normals: np.ndarray, block: int = BLOCK_SAMPLES
) -> tuple[np.ndarray, np.ndarray]:
    """The crossing of the polyline ``path`` (n, d) with the plane of each station nearest that station.

    Parameters
    ----------
    path : ndarray, shape (n, d)
        The attained samples, finite, in order.
    stations, normals : ndarray, shape (m, d)
        A point of each plane and its unit normal.
    block : int
        Samples per block of the box test (any positive size gives the same crossings).

    Returns
    -------
    index : ndarray of int, shape (m,)
        The sample k each crossing starts from; -1 where the path never crosses the station's plane.
    fraction : ndarray, shape (m,)
        f, 0 <= f <= 1: the crossing is path[k] + f (path[k + 1] - path[k]) (path[k] itself at the last sample).
    """
    index, fraction = np.full(len(stations), -1), np.zeros(len(stations))
    if len(path) == 0:
        return index, fraction
    per_chunk = max(1, _BOX_TESTS // (len(path) // block + 1))  # the box tests' memory bounded, whatever the path
    for first in range(0, len(stations), per_chunk):
        chunk = slice(first, first + per_chunk)
        index[chunk], fraction[chunk] = _nearest_crossings(path, stations[chunk], normals[chunk], block)
    return index, fraction


def _nearest_crossings(
    path: np.ndarray, stations: np.ndarray, normals: np.ndarray, block: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`plane_crossings` for stations whose box tests fit in memory."""
    n, m = len(path), len(stations)
    index, fraction = np.full(m, -1), np.zeros(m)
    starts = np.arange(0, max(n - 1, 1), block)
    ends = np.minimum(starts + block, n - 1)  # a block's box holds its samples [start, end], the end shared
    lo = np.minimum(np.minimum.reduceat(path, starts, axis=0), path[ends])
    hi = np.maximum(np.maximum.reduceat(path, starts, axis=0), path[ends])
    # per block and station, the lowest and highest δ of the box's corners (the term's low end is lo or hi by n's sign)
    low_end = np.where(normals[None] >= 0, lo[:, None], hi[:, None])
    high_end = np.where(normals[None] >= 0, hi[:, None], lo[:, None])
    cut = (_signed(low_end, stations[None], normals[None]) <= 0) & (
        _signed(high_end, stations[None], normals[None]) >= 0
    )
    blocks, station = np.nonzero(cut)
    if len(blocks) == 0:
        return index, fraction
    # every sample a cut block owns ([start, end): its segments k -> k + 1; the last block owns the last sample too)
    k = starts[blocks][:, None] + np.arange(block + 1)[None, :]
    owned = (k < ends[blocks][:, None]) | ((k == n - 1) & (blocks == len(starts) - 1)[:, None])
    k, station = k[owned], np.broadcast_to(station[:, None], owned.shape)[owned]
    after = np.minimum(k + 1, n - 1)
    here = _signed(path[k], stations[station], normals[station])
    there = _signed(path[after], stations[station], normals[station])
    zero = here == 0.0
    crossing = (k < n - 1) & (np.signbit(here) != np.signbit(there))
    # a zero and a sign change at the same sample are two candidates, as the per-station reading lists them
    pick = np.concatenate([np.flatnonzero(zero), np.flatnonzero(crossing)])
    is_crossing = np.concatenate([np.zeros(zero.sum(), bool), np.ones(crossing.sum(), bool)])
    if len(pick) == 0:  # boxes cut, samples not (the box holds the plane, the polyline passes it by)
        return index, fraction
    k, station, after = k[pick], station[pick], after[pick]
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(is_crossing, here[pick] / (here[pick] - there[pick]), 0.0)
    points = path[k] + f[:, None] * (path[after] - path[k])
    gap = points - stations[station]
    distance = gap[:, 0] ** 2
    for axis in range(1, gap.shape[1]):
        distance = distance + gap[:, axis] ** 2
    order = np.lexsort((k, is_crossing, distance, station))  # nearest; then a zero; then the earlier sample
    first = order[np.r_[True, station[order][1:] != station[order][:-1]]]
    index[station[first]], fraction[station[first]] = k[first], f[first]
    return index, fraction
