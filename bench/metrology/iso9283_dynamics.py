"""ISO 9283:1998 characteristics that need a time series or a sampled path: drift, stabilisation, overshoot, AT/RT.

These need a continuous stream (a high-rate mouse, a tracker, a dial indicator with data output); a static
calliper reading cannot give them. Positions in mm, times in s. Formulas from ``shared/reference/iso9283.md``
§6.6-§6.8, §6.10 and §6.11, all tagged [U]: verify them against a licensed copy of the standard.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError, InsufficientData
from bench.metrology._validation import (
    as_points,
    as_series,
    as_vector,
    require_count,
    require_same_length,
)
from bench.metrology.iso9283 import orientation_accuracy, orientation_repeatability
from bench.metrology.plane_crossings import plane_crossings

__all__ = [
    "PathCharacteristics",
    "PoseDrift",
    "OrientationDrift",
    "PoseStabilisation",
    "Stabilisation",
    "crossing_characteristics",
    "cycle_crossings",
    "orientation_drift",
    "path_characteristics",
    "pose_drift",
    "pose_stabilisation",
    "position_stabilisation",
]


@dataclass(frozen=True, eq=False)
class PoseDrift:
    """Drift of AP and RP between the first and last time window (ISO 9283 7.6)."""

    dap_mm: float  #: |AP(first window) - AP(last window)|
    drp_mm: float  #: |RP(first window) - RP(last window)|
    window_start_s: np.ndarray  #: (k,) start time of each non-empty window
    ap_mm: np.ndarray  #: (k,) AP_P per window
    rp_mm: np.ndarray  #: (k,) RP_l per window
    n_per_window: np.ndarray  #: (k,) samples per window


@dataclass(frozen=True, eq=False)
class OrientationDrift:
    """Drift of AP_a/b/c and RP_a/b/c between the first and last time window (ISO 9283 7.6)."""

    dap_deg: tuple[float, ...]  #: per angle |AP_a(first window) - AP_a(last window)|
    drp_deg: tuple[float, ...]  #: per angle |RP_a(first window) - RP_a(last window)|
    window_start_s: np.ndarray  #: (k,)
    ap_deg: np.ndarray  #: (k, q) signed AP_a per window
    rp_deg: np.ndarray  #: (k, q) RP_a = 3 S_a per window
    n_per_window: np.ndarray  #: (k,)


@dataclass(frozen=True)
class Stabilisation:
    """Position stabilisation time and overshoot of one move (ISO 9283 7.4 and 7.5)."""

    stabilisation_time_s: float  #: t_2 - t_1 >= 0
    first_entry_s: float  #: t_1, first time inside the limit band
    settled_s: float  #: t_2, from when on the position stays inside the band
    overshoot_mm: float  #: max distance after t_1 if it exceeds the band, else 0
    band_mm: float
    peak_s: float  #: time of the largest distance after t_1 (where OV is read; OV = 0 when inside B + h)


@dataclass(frozen=True)
class PoseStabilisation:
    """Stabilisation time and overshoot at one pose over its n cycles (ISO 9283 7.4, 7.5; n = 3)."""

    mean_time_s: float  #: mean of t_s over the cycles (the ISO figure)
    max_time_s: float
    mean_overshoot_mm: float  #: OV = mean of OV_j (the ISO figure)
    max_overshoot_mm: float  #: max_j OV_j, reported with it
    cycles: tuple[Stabilisation, ...]


@dataclass(frozen=True, eq=False)
class PathCharacteristics:
    """Path accuracy AT_p and repeatability RT_p over the stations of a commanded path (ISO 9283 8.2, 8.3)."""

    at_mm: float  #: max over stations of the distance barycentre - commanded point
    rt_mm: float  #: max over stations of l̄_i + 3 S_li
    at_per_station_mm: np.ndarray  #: (m,)
    rt_per_station_mm: np.ndarray  #: (m,)
    n_cycles: int


def _drift_windows(times: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Window numbers present, the window of each sample and the samples per window (each >= 2, at least 2)."""
    if not window_s > 0:
        raise ConfigError(f"window_s = {window_s}, expected a number > 0")
    raw_index = np.floor((times - times.min()) / window_s).astype(np.int64)
    occupied, window = np.unique(raw_index, return_inverse=True)
    require_count("drift windows", len(occupied), 2)
    counts = np.bincount(window)
    if counts.min() < 2:
        first_sparse = int(occupied[np.argmin(counts)])
        require_count(f"drift window starting at t = {times.min() + first_sparse * window_s:g} s", counts.min(), 2)
    return occupied, window, counts


def pose_drift(t_s: ArrayLike, attained_mm: ArrayLike, commanded_mm: ArrayLike, *, window_s: float) -> PoseDrift:
    """Drift of pose accuracy and repeatability over time windows (ISO 9283 7.6 [U]).

    The samples, all at one command pose, are cut into consecutive windows of ``window_s`` seconds from the first
    sample; AP_P and RP_l are computed per non-empty window, and

    .. math:: dAP = |AP_{t=1} - AP_{t=T}|, \\quad dRP = |RP_{t=1} - RP_{t=T}|

    with t = 1 the first window and t = T the last. Vectorised with ``np.bincount``: 10^6 samples take a few
    tens of milliseconds.

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times (s), any order.
    attained_mm : array_like, shape (n, d)
        Attained positions (mm).
    commanded_mm : array_like, shape (d,)
        Command position (mm).
    window_s : float
        Window length (s), > 0.

    Raises
    ------
    InsufficientData
        Fewer than 2 non-empty windows, or a non-empty window with fewer than 2 samples.
    """
    times = as_series("t_s", t_s, min_count=1)
    attained = as_points("attained_mm", attained_mm)
    require_same_length("t_s", times, "attained_mm", attained)
    command = as_vector("commanded_mm", commanded_mm, length=attained.shape[1])
    occupied, window, counts = _drift_windows(times, window_s)
    barycentre = np.stack([np.bincount(window, weights=col) for col in attained.T], axis=1) / counts[:, None]
    ap = np.sqrt(np.sum((barycentre - command) ** 2, axis=1))
    distance = np.sqrt(np.sum((attained - barycentre[window]) ** 2, axis=1))
    l_mean = np.bincount(window, weights=distance) / counts
    l_var = np.bincount(window, weights=(distance - l_mean[window]) ** 2) / (counts - 1)
    rp = l_mean + 3.0 * np.sqrt(l_var)
    return PoseDrift(
        dap_mm=float(abs(ap[0] - ap[-1])),
        drp_mm=float(abs(rp[0] - rp[-1])),
        window_start_s=times.min() + occupied * window_s,
        ap_mm=ap,
        rp_mm=rp,
        n_per_window=counts,
    )


def orientation_drift(
    t_s: ArrayLike, attained_deg: ArrayLike, commanded_deg: ArrayLike, *, window_s: float
) -> OrientationDrift:
    """Drift of orientation accuracy and repeatability over time windows (ISO 9283 7.6 [U]).

    Windows as in :func:`pose_drift`; per window AP_a = ā - a_c (circular mean, wrapped) and RP_a = 3 S_a
    (ISO 9283 7.2.1, 7.2.2), then

    .. math:: dAP_a = |AP_{a,t=1} - AP_{a,t=T}|, \\quad dRP_a = |RP_{a,t=1} - RP_{a,t=T}| \\quad (\\text{likewise } b, c)

    Parameters
    ----------
    t_s : array_like, shape (n,)
        Sample times (s), any order.
    attained_deg : array_like, shape (n, q)
        Attained angles a, b, c (deg), q = 1..3.
    commanded_deg : array_like, shape (q,)
        Command angles (deg).
    window_s : float
        Window length (s), > 0.
    """
    times = as_series("t_s", t_s, min_count=1)
    attained = as_points("attained_deg", attained_deg)
    require_same_length("t_s", times, "attained_deg", attained)
    command = as_vector("commanded_deg", commanded_deg, length=attained.shape[1])
    occupied, window, counts = _drift_windows(times, window_s)
    ap = np.array([orientation_accuracy(attained[window == w], command).ap_deg for w in range(len(occupied))])
    rp = np.array([orientation_repeatability(attained[window == w]).rp_deg for w in range(len(occupied))])
    return OrientationDrift(
        dap_deg=tuple(float(v) for v in np.abs(ap[0] - ap[-1])),
        drp_deg=tuple(float(v) for v in np.abs(rp[0] - rp[-1])),
        window_start_s=times.min() + occupied * window_s,
        ap_deg=ap,
        rp_deg=rp,
        n_per_window=counts,
    )


def position_stabilisation(
    t_s: ArrayLike,
    position_mm: ArrayLike,
    *,
    band_mm: float,
    final_mm: ArrayLike | None = None,
    hysteresis_mm: float = 0.0,
) -> Stabilisation:
    """Stabilisation time and overshoot of one move towards a pose, from a sampled time series.

    ISO 9283:1998 clauses 7.4 and 7.5 [U]; limit bands 0.1, 0.5 and 1.0 mm for comparison tests [N]:

    .. math::

        d(t) = \\lVert p(t) - p_{att} \\rVert, \\quad t_1 = \\min\\{t : d(t) \\le B\\}, \\quad
        t_2 = \\min\\{t \\ge t_1 : d(\\tau) \\le B + h \\ \\forall \\tau \\ge t\\}, \\quad t_s = t_2 - t_1

        OV = \\max_{t \\ge t_1} d(t) \\text{ if it exceeds } B + h, \\text{ else } 0

    The hysteresis h (default 0, the standard's definition) is for quantised, noisy instruments: a slow approach
    dithers across the band edge by a count, and without it every such flicker after the first entry would read as
    an overshoot of about B. With h set to the instrument's resolution (one count of a mouse: 25.4 / CPI mm), only
    excursions the instrument can tell from the band edge count.

    Parameters
    ----------
    t_s : array_like, shape (m,)
        Sample times (s), strictly increasing.
    position_mm : array_like, shape (m, d)
        Measured positions (mm).
    band_mm : float
        Limit band B (mm), > 0.
    final_mm : array_like, shape (d,), optional
        Settled attained position p_att; by default the last sample.
    hysteresis_mm : float
        h >= 0 (mm), see above.

    Raises
    ------
    InsufficientData
        Fewer than 2 samples, or the series never enters the band (there is then no t_1).
    """
    times = as_series("t_s", t_s, min_count=2)
    position = as_points("position_mm", position_mm)
    require_same_length("t_s", times, "position_mm", position)
    if np.any(np.diff(times) <= 0):
        raise ConfigError("t_s: times are not strictly increasing")
    if not band_mm > 0:
        raise ConfigError(f"band_mm = {band_mm}, expected a number > 0")
    if not hysteresis_mm >= 0:
        raise ConfigError(f"hysteresis_mm = {hysteresis_mm}, expected a number >= 0")
    final = position[-1] if final_mm is None else np.asarray(final_mm, dtype=float)
    distance = np.sqrt(np.sum((position - final) ** 2, axis=1))
    inside = distance <= band_mm
    if not inside.any():
        raise InsufficientData(f"stabilisation: the series never enters the {band_mm:g} mm band")
    first = int(np.argmax(inside))
    outside_after = np.flatnonzero(distance[first:] > band_mm + hysteresis_mm)
    settled = first if len(outside_after) == 0 else first + int(outside_after[-1]) + 1
    if settled >= len(times):
        raise InsufficientData("stabilisation: the series ends outside the limit band")
    peak_index = first + int(np.argmax(distance[first:]))
    peak = float(distance[peak_index])
    return Stabilisation(
        stabilisation_time_s=float(times[settled] - times[first]),
        first_entry_s=float(times[first]),
        settled_s=float(times[settled]),
        overshoot_mm=peak if peak > band_mm + hysteresis_mm else 0.0,
        band_mm=float(band_mm),
        peak_s=float(times[peak_index]),
    )


def pose_stabilisation(
    series: Sequence[tuple[ArrayLike, ArrayLike]], *, band_mm: float, hysteresis_mm: float = 0.0
) -> PoseStabilisation:
    """Stabilisation time and overshoot of the n arrivals at one pose (ISO 9283 7.4, 7.5 [U]; n = 3 [N]).

    Each arrival is analysed with :func:`position_stabilisation` against its own settled position (its last
    sample), then

    .. math:: \\bar t_s = \\frac1n \\sum_j t_{s,j}, \\qquad OV = \\frac1n \\sum_j OV_j, \\qquad \\max_j OV_j

    Parameters
    ----------
    series : sequence of (t_s, position_mm)
        One time series per cycle: times (m_j,) in s, positions (m_j, d) in mm.
    band_mm : float
        Limit band B (mm).
    hysteresis_mm : float
        Instrument hysteresis h (mm), as in :func:`position_stabilisation`.

    Raises
    ------
    InsufficientData
        No series, or a series that never settles in the band.
    """
    require_count("arrivals", len(series), 1)
    cycles = tuple(position_stabilisation(t, p, band_mm=band_mm, hysteresis_mm=hysteresis_mm) for t, p in series)
    times = np.array([c.stabilisation_time_s for c in cycles])
    overshoots = np.array([c.overshoot_mm for c in cycles])
    return PoseStabilisation(
        float(times.mean()), float(times.max()), float(overshoots.mean()), float(overshoots.max()), cycles
    )


def _station_normals(stations: np.ndarray) -> np.ndarray:
    """Unit normals of the station planes: the commanded path's direction by central differences."""
    tangents = np.gradient(stations, axis=0)
    norms = np.linalg.norm(tangents, axis=1)
    if np.any(norms == 0):
        raise ConfigError("commanded_mm: repeated stations, the path direction is undefined there")
    return tangents / norms[:, None]


def station_crossings(
    paths_mm: Sequence[ArrayLike], commanded_mm: ArrayLike
) -> tuple[np.ndarray, list[list[tuple[int, float]]]]:
    """Cut every attained path with the plane normal to the commanded path at each station (ISO 9283 8.2).

    Returns the intersection points, shape (m stations, n cycles, d), and per station and cycle the crossing as
    (sample index i, fraction f) so that other sampled quantities (angles) can be read at the same place.
    """
    stations = as_points("commanded_mm", commanded_mm, dims=(2, 3))
    require_count("commanded path stations", len(stations), 2)
    require_count("path cycles", len(paths_mm), 2)
    paths = [as_points(f"paths_mm[{j}]", p, dims=(stations.shape[1],)) for j, p in enumerate(paths_mm)]
    tangents = _station_normals(stations)
    points = np.empty((len(stations), len(paths), stations.shape[1]))
    where: list[list[tuple[int, float]]] = []
    hits = [plane_crossings(path, stations, tangents) for path in paths]
    for i in range(len(stations)):
        where.append([])
        for j, (path, (index, fractions)) in enumerate(zip(paths, hits)):
            if index[i] < 0:
                raise InsufficientData(f"path cycle {j} never crosses the plane of station {i}")
            k, fraction = int(index[i]), float(fractions[i])
            points[i, j] = path[k] + fraction * (path[min(k + 1, len(path) - 1)] - path[k])
            where[i].append((k, fraction))
    return points, where


def cycle_crossings(path_mm: ArrayLike, commanded_mm: ArrayLike) -> tuple[np.ndarray, int | None]:
    """One cycle's column of :func:`station_crossings`, the same numbers: ``(points (m, d), missed)`` with
    ``missed`` the first station whose plane the path never crosses (its row NaN), None when it crosses them all.

    A long run is reduced to this, cycle by cycle, as its samples are read (:func:`crossing_characteristics`
    takes the columns): memory by the cycle, not the run.
    """
    stations = as_points("commanded_mm", commanded_mm, dims=(2, 3))
    require_count("commanded path stations", len(stations), 2)
    path = as_points("path_mm", path_mm, dims=(stations.shape[1],))
    index, fraction = plane_crossings(path, stations, _station_normals(stations))
    crossed = index >= 0
    points = np.full(stations.shape, np.nan)
    k = index[crossed]
    points[crossed] = path[k] + fraction[crossed, None] * (path[np.minimum(k + 1, len(path) - 1)] - path[k])
    return points, (None if crossed.all() else int(np.argmin(crossed)))


def crossing_characteristics(points_mm: np.ndarray, commanded_mm: ArrayLike) -> PathCharacteristics:
    """AT_p, RT_p (:func:`path_characteristics`) from the crossing points, shape (m stations, n cycles, d)."""
    stations = as_points("commanded_mm", commanded_mm, dims=(2, 3))
    barycentres = points_mm.mean(axis=1)
    at = np.linalg.norm(barycentres - stations, axis=1)
    distances = np.linalg.norm(points_mm - barycentres[:, None, :], axis=2)
    rt = distances.mean(axis=1) + 3.0 * distances.std(axis=1, ddof=1)
    return PathCharacteristics(
        at_mm=float(at.max()),
        rt_mm=float(rt.max()),
        at_per_station_mm=at,
        rt_per_station_mm=rt,
        n_cycles=points_mm.shape[1],
    )


def path_characteristics(paths_mm: Sequence[ArrayLike], commanded_mm: ArrayLike) -> PathCharacteristics:
    """Path accuracy AT_p and path repeatability RT_p from sampled paths (ISO 9283 8.2, 8.3 [U]).

    The commanded path is given as m stations; the plane at station i is normal to the commanded path there
    (central differences of the stations). Each attained path (a polyline) is intersected with every plane by
    linear interpolation between the two samples that bracket it; of several crossings the one nearest the
    station is used. With x̄_i the barycentre of the n intersection points in plane i:

    .. math::

        AT_p = \\max_i \\lVert \\bar p_i - p_{ci} \\rVert, \\quad
        RT_p = \\max_i (\\bar l_i + 3 S_{li}), \\quad l_{ij} = \\lVert p_{ij} - \\bar p_i \\rVert

    Parameters
    ----------
    paths_mm : sequence of array_like, each shape (k_j, d)
        One sampled attained path per cycle (ISO: 10 cycles); d = 2 or 3.
    commanded_mm : array_like, shape (m, d)
        Stations along the commanded path, m >= 2, in order of travel.

    Raises
    ------
    InsufficientData
        Fewer than 2 cycles, or a path that never crosses a station's plane.
    """
    stations = as_points("commanded_mm", commanded_mm, dims=(2, 3))
    points, _ = station_crossings(paths_mm, stations)
    return crossing_characteristics(points, stations)
