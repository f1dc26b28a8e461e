"""ISO 9283:1998 clauses 8.5, 8.6 and 9: cornering deviations, path velocity characteristics, minimum positioning time.

Pure functions over sampled paths and time series (positions in mm, times in s, velocities in mm/s). Formulas from
``shared/reference/iso9283.md`` §6.13 (8.5, tagged [U]), §6.14 (8.6, [U]) and §6.15 (clause 9: the step table and
the test conditions [N], the definition of the time [U]); the cycle counts of Table 5 are [N]: 3 for cornering,
10 for path velocity, 3 for minimum positioning time. Where the standard's wording was not available the method
choice is stated in the docstring; verify against a licensed copy before a report labels a figure "ISO".
Position path accuracy and repeatability AT_p/RT_p (8.2, 8.3) are in `iso9283_dynamics`; their orientation
counterparts AT_a/b/c and RT_a/b/c (8.2, 8.3, and 8.4 on reorientation) are here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError, InsufficientData
from bench.metrology._validation import as_points, as_series, as_vector, require_count, require_same_length
from bench.metrology.iso9283 import circular_mean_deg, wrap_deg
from bench.metrology.iso9283_dynamics import position_stabilisation, station_crossings

__all__ = [
    "MIN_POSITIONING_STEPS_MM",
    "CorneringDeviations",
    "MinimumPositioningTime",
    "PathOrientation",
    "PathVelocity",
    "cornering_deviations",
    "minimum_positioning_targets",
    "minimum_positioning_time",
    "path_orientation_characteristics",
    "path_speed",
    "path_velocity_characteristics",
]

#: ISO 9283 clause 9, Table 19 [N]: distance of each step from the previous pose (mm), with Dx = Dy = Dz.
MIN_POSITIONING_STEPS_MM = (-10.0, 20.0, -50.0, 100.0, -200.0, 500.0, -1000.0)


@dataclass(frozen=True)
class CorneringDeviations:
    """Cornering round-off CR and overshoot CO at one commanded corner over n cycles (ISO 9283 8.5)."""

    cr_mm: float  #: max_j CR_j (the worst cycle)
    co_mm: float  #: max_j CO_j
    mean_cr_mm: float
    mean_co_mm: float
    cr_per_cycle_mm: tuple[float, ...]  #: CR_j = min_t |P_E - p_j(t)| >= 0
    co_per_cycle_mm: tuple[float, ...]  #: CO_j >= 0, outward deviation from the next segment after the corner
    n: int


@dataclass(frozen=True, eq=False)
class PathOrientation:
    """Orientation path accuracy AT_a/b/c and repeatability RT_a/b/c (ISO 9283 8.2, 8.3, 8.4)."""

    at_deg: tuple[float, ...]  #: per angle, max_i |ā_i - a_ci|
    rt_deg: tuple[float, ...]  #: per angle, max_i 3 S_ai, reported as ±
    at_per_station_deg: np.ndarray  #: (m, q) signed ā_i - a_ci
    rt_per_station_deg: np.ndarray  #: (m, q) 3 S_ai
    n_cycles: int


@dataclass(frozen=True)
class PathVelocity:
    """Path velocity accuracy AV, repeatability RV and fluctuation FV (ISO 9283 8.6)."""

    av_pct: float  #: (v̄ - v_c) / v_c × 100, signed: negative when the robot is slow
    rv_pct: float  #: 3 S_v / v_c × 100 >= 0, reported as ±
    fv_mm_s: float  #: max_j (max_i v_ij - min_i v_ij) >= 0
    mean_speed_mm_s: float  #: v̄
    mean_speed_per_cycle_mm_s: tuple[float, ...]  #: v̄_j
    commanded_mm_s: float  #: v_c
    n: int


@dataclass(frozen=True)
class MinimumPositioningTime:
    """Positioning time per step of the clause 9 sequence, over n cycles (ISO 9283 9)."""

    mean_time_s: tuple[float, ...]  #: per step, mean over the cycles (the ISO figure)
    max_time_s: tuple[float, ...]  #: per step, the slowest cycle
    time_s_per_cycle: tuple[tuple[float, ...], ...]  #: [step][cycle]
    step_distance_mm: tuple[float, ...]  #: per step, mean attained |p_end - p_start|
    band_mm: float
    n: int


def _unit(name: str, vector: np.ndarray) -> np.ndarray:
    norm = float(np.linalg.norm(vector))
    if norm == 0.0:
        raise ConfigError(f"{name}: zero-length segment, expected two distinct points")
    return vector / norm


def _nearest_on_polyline(point: np.ndarray, path: np.ndarray) -> tuple[float, int, np.ndarray]:
    """Least distance from ``point`` to the polyline ``path``, the first segment where it occurs, and the point."""
    if len(path) == 1:
        return float(np.linalg.norm(path[0] - point)), 0, path[0]
    start, step = path[:-1], np.diff(path, axis=0)
    length2 = np.sum(step**2, axis=1)
    fraction = np.divide(np.sum((point - start) * step, axis=1), length2, out=np.zeros(len(step)), where=length2 > 0)
    nearest = start + np.clip(fraction, 0.0, 1.0)[:, None] * step
    distance = np.linalg.norm(nearest - point, axis=1)
    # ties (a path that passes the corner twice at the same distance) go to the first pass, also after rounding
    tolerance = 1e-9 * max(1.0, float(np.abs(path - point).max()))
    best = int(np.flatnonzero(distance <= distance.min() + tolerance)[0])
    return float(distance.min()), best, nearest[best]


def cornering_deviations(
    paths_mm: Sequence[ArrayLike], corner_mm: ArrayLike, incoming_from_mm: ArrayLike, outgoing_to_mm: ArrayLike
) -> CorneringDeviations:
    """Cornering round-off error CR and cornering overshoot CO at one sharp corner (ISO 9283 8.5 [U]; n = 3 [N]).

    With P_E the commanded corner, u_in and u_out the unit directions of the commanded segments into and out of
    it, and p_j(t) the attained path of cycle j read as a polyline (linear between samples):

    .. math::

        CR_j = \\min_t \\lVert P_E - p_j(t) \\rVert, \\qquad
        CO_j = \\max\\Big(0,\\ \\max_{t \\ge t^*_j} (p_j(t) - P_E) \\cdot \\hat n\\Big), \\qquad
        \\hat n = \\frac{u_{in} - (u_{in} \\cdot u_{out})\\, u_{out}}{\\lVert \\cdot \\rVert}

    where t*_j is where CR_j is first attained. ``n̂`` points across the outgoing segment towards the side the robot
    arrives from, so CO is the overshoot beyond the outgoing segment; the inside cut of a rounded corner counts in
    CR, not in CO (a method choice, [P], for the standard's "largest deviation from the commanded path after the
    corner"). CO is exact for the polyline: the offset is linear along each segment, so its maximum is at a sample.

    Parameters
    ----------
    paths_mm : sequence of array_like, each shape (k_j, d)
        One attained path through the corner per cycle, samples in order of travel, d = 2 or 3.
    corner_mm, incoming_from_mm, outgoing_to_mm : array_like, shape (d,)
        The commanded corner P_E, the start of the commanded segment into it, the end of the one out of it.

    Raises
    ------
    InsufficientData
        No cycle.
    ConfigError
        Straight or reversing "corners" (u_in parallel to u_out), zero-length segments, mismatched dimensions.

    Examples
    --------
    A square corner at the origin, reached along +x and left along +y. The first cycle cuts the corner by a
    chord from (-1, 0) to (0, 1); the second runs 0.5 mm past it before turning:

    >>> cut = [[-10, 0], [-1, 0], [0, 1], [0, 10]]
    >>> past = [[-10, 0], [0.5, 0], [0.5, 0.5], [0, 1], [0, 10]]
    >>> r = cornering_deviations([cut, past], [0, 0], [-10, 0], [0, 10])
    >>> [round(v, 4) for v in r.cr_per_cycle_mm], [round(v, 4) for v in r.co_per_cycle_mm]
    ([0.7071, 0.0], [0.0, 0.5])
    """
    require_count("cornering cycles", len(paths_mm), 1)
    corner = as_vector("corner_mm", corner_mm, length=np.size(corner_mm))
    if corner.shape[0] not in (2, 3):
        raise ConfigError(f"corner_mm: {corner.shape[0]} coordinates, expected 2 or 3")
    d = corner.shape[0]
    u_in = _unit("incoming_from_mm -> corner_mm", corner - as_vector("incoming_from_mm", incoming_from_mm, length=d))
    u_out = _unit("corner_mm -> outgoing_to_mm", as_vector("outgoing_to_mm", outgoing_to_mm, length=d) - corner)
    across = u_in - (u_in @ u_out) * u_out
    if np.linalg.norm(across) < 1e-9:
        raise ConfigError("cornering: the segments into and out of the corner are parallel, expected a corner")
    across /= np.linalg.norm(across)
    cr, co = [], []
    for j, raw in enumerate(paths_mm):
        path = as_points(f"paths_mm[{j}]", raw, dims=(d,))
        distance, segment, nearest = _nearest_on_polyline(corner, path)
        after = np.vstack([nearest, path[segment + 1 :]])
        cr.append(distance)
        co.append(max(0.0, float(((after - corner) @ across).max())))
    return CorneringDeviations(max(cr), max(co), float(np.mean(cr)), float(np.mean(co)), tuple(cr), tuple(co), len(cr))


def path_orientation_characteristics(
    paths_mm: Sequence[ArrayLike], angles_deg: Sequence[ArrayLike], commanded_mm: ArrayLike, commanded_deg: ArrayLike
) -> PathOrientation:
    """Orientation path accuracy AT_a and repeatability RT_a (ISO 9283 8.2, 8.3; 8.4 on reorientation [U]).

    Each attained path is cut with the plane normal to the commanded path at every station, as for AT_p
    (:func:`~bench.metrology.iso9283_dynamics.path_characteristics`); the angles are read at the same crossing by
    linear interpolation between the two bracketing samples (along the shorter arc). With a_ij the angle of cycle
    j in plane i and a_ci the commanded angle there:

    .. math::

        AT_a = \\max_i |\\bar a_i - a_{ci}|, \\qquad RT_a = \\pm \\max_i 3 S_{ai}, \\qquad
        S_{ai} = \\sqrt{\\frac{\\sum_j (a_{ij} - \\bar a_i)^2}{n - 1}}

    (likewise b, c); ā_i is the circular mean and differences are wrapped to [-180, 180).

    Parameters
    ----------
    paths_mm : sequence of array_like, each shape (k_j, d)
        Attained positions per cycle, in order of travel (n >= 2 cycles; ISO: 10).
    angles_deg : sequence of array_like, each shape (k_j, q)
        Attained angles sampled with those positions, q = 1..3 (deg).
    commanded_mm : array_like, shape (m, d)
        Stations along the commanded path.
    commanded_deg : array_like, shape (m, q)
        Commanded angles at the stations (deg): constant for 8.2, the prescribed changes for 8.4.

    Examples
    --------
    Two straight passes along x, 0.2° and 0.4° above a commanded ramp a_c = 0.1°/mm · x (mean 0.3° above):

    >>> line = [[0.0, 0.0], [10.0, 0.0]]
    >>> r = path_orientation_characteristics([line, line], [[[0.2], [1.2]], [[0.4], [1.4]]],
    ...                                      [[2.0, 0.0], [8.0, 0.0]], [[0.2], [0.8]])
    >>> [round(v, 6) for v in r.at_deg], [round(v, 4) for v in r.rt_deg]
    ([0.3], [0.4243])
    """
    points, where = station_crossings(paths_mm, commanded_mm)
    if len(angles_deg) != len(paths_mm):
        raise ConfigError(f"angles_deg has {len(angles_deg)} cycles and paths_mm {len(paths_mm)}, expected the same")
    angles = [as_points(f"angles_deg[{j}]", a) for j, a in enumerate(angles_deg)]
    if len({a.shape[1] for a in angles}) != 1:
        raise ConfigError(f"angles_deg: cycles with different angle counts {[a.shape[1] for a in angles]}")
    for j, (a, p) in enumerate(zip(angles, paths_mm)):
        rows = np.shape(p)[0]
        if len(a) != rows:
            raise ConfigError(f"angles_deg[{j}] has {len(a)} rows and paths_mm[{j}] {rows}, expected the same")
    q = angles[0].shape[1]
    commanded = as_points("commanded_deg", commanded_deg, dims=(q,))
    if len(commanded) != points.shape[0]:
        raise ConfigError(
            f"commanded_deg has {len(commanded)} rows and commanded_mm {points.shape[0]}, expected one per station"
        )
    at_station = np.empty((points.shape[0], points.shape[1], q))
    for i, row in enumerate(where):
        for j, (k, fraction) in enumerate(row):
            a = angles[j]
            after = a[min(k + 1, len(a) - 1)]
            at_station[i, j] = a[k] + fraction * wrap_deg(after - a[k])
    means = np.array([circular_mean_deg(cloud) for cloud in at_station])
    accuracy = wrap_deg(means - commanded)
    spread = wrap_deg(at_station - means[:, None, :])
    repeatability = 3.0 * np.sqrt(np.sum(spread**2, axis=1) / (points.shape[1] - 1))
    return PathOrientation(
        at_deg=tuple(float(v) for v in np.abs(accuracy).max(axis=0)),
        rt_deg=tuple(float(v) for v in repeatability.max(axis=0)),
        at_per_station_deg=accuracy,
        rt_per_station_deg=repeatability,
        n_cycles=points.shape[1],
    )


def path_speed(t_s: ArrayLike, position_mm: ArrayLike) -> np.ndarray:
    """Path speed samples from a sampled path: v_i = |p_{i+1} - p_i| / (t_{i+1} - t_i), shape (m - 1,), mm/s.

    The speed between consecutive samples, the velocity samples v_ij of ISO 9283 8.6 for an instrument that reads
    positions. Quantisation of the positions enters v_i as (resolution / Δt): sample no faster than the
    instrument's resolution allows.

    Examples
    --------
    >>> path_speed([0.0, 0.1, 0.2], [[0, 0], [3, 4], [3, 4.5]]).tolist()
    [50.0, 5.0]
    """
    times = as_series("t_s", t_s, min_count=2)
    position = as_points("position_mm", position_mm)
    require_same_length("t_s", times, "position_mm", position)
    step_s = np.diff(times)
    if np.any(step_s <= 0):
        raise ConfigError("t_s: times are not strictly increasing")
    return np.linalg.norm(np.diff(position, axis=0), axis=1) / step_s


def path_velocity_characteristics(speeds_mm_s: Sequence[ArrayLike], commanded_mm_s: float) -> PathVelocity:
    """Path velocity accuracy AV, repeatability RV and fluctuation FV (ISO 9283 8.6 [U]; n = 10 [N]).

    Over the constant-velocity part of a straight path, with v_ij the i-th speed sample of cycle j (m_j samples)
    and v_c the commanded path velocity:

    .. math::

        \\bar v_j = \\frac1{m_j} \\sum_i v_{ij}, \\quad \\bar v = \\frac1n \\sum_j \\bar v_j, \\quad
        AV = \\frac{\\bar v - v_c}{v_c} \\, 100\\,\\%, \\quad
        RV = \\pm \\frac{3 S_v}{v_c} \\, 100\\,\\%, \\quad S_v = \\sqrt{\\frac{\\sum_j (\\bar v_j - \\bar v)^2}{n - 1}},
        \\quad FV = \\max_j \\big(\\max_i v_{ij} - \\min_i v_{ij}\\big)

    Parameters
    ----------
    speeds_mm_s : sequence of array_like, each shape (m_j,)
        Speed samples per cycle (mm/s), e.g. from :func:`path_speed`; n >= 2 cycles.
    commanded_mm_s : float
        Commanded path velocity v_c (mm/s), > 0.

    Examples
    --------
    >>> r = path_velocity_characteristics([[10, 12], [11, 11], [9, 13]], 10.0)
    >>> round(r.av_pct, 6), round(r.rv_pct, 6), r.fv_mm_s
    (10.0, 0.0, 4.0)
    """
    if not commanded_mm_s > 0:
        raise ConfigError(f"commanded_mm_s = {commanded_mm_s}, expected a velocity > 0 mm/s")
    require_count("path velocity cycles", len(speeds_mm_s), 2)
    cycles = [as_series(f"speeds_mm_s[{j}]", v, min_count=1) for j, v in enumerate(speeds_mm_s)]
    means = np.array([v.mean() for v in cycles])
    mean = float(means.mean())
    return PathVelocity(
        av_pct=(mean - commanded_mm_s) / commanded_mm_s * 100.0,
        rv_pct=3.0 * float(means.std(ddof=1)) / commanded_mm_s * 100.0,
        fv_mm_s=float(max(v.max() - v.min() for v in cycles)),
        mean_speed_mm_s=mean,
        mean_speed_per_cycle_mm_s=tuple(float(v) for v in means),
        commanded_mm_s=float(commanded_mm_s),
        n=len(cycles),
    )


def minimum_positioning_targets(p1_mm: ArrayLike, steps_mm: Sequence[float] = MIN_POSITIONING_STEPS_MM) -> np.ndarray:
    """The poses P1+1 .. P1+k of the clause 9 step sequence, shape (k, d), reading each step as a per-axis increment.

    ISO 9283 clause 9, Table 19 [N] gives the step distances with the condition Dx = Dy = Dz; reading them as
    per-axis increments (the Euclidean step is then √d times longer) is [U]. Targets that leave the workspace are
    for the protocol's pre-flight to drop.

    Examples
    --------
    >>> minimum_positioning_targets([0.0])[:, 0].tolist()
    [-10.0, 10.0, -40.0, 60.0, -140.0, 360.0, -640.0]
    """
    start = as_vector("p1_mm", p1_mm, length=np.size(p1_mm))
    offsets = np.cumsum(np.asarray(steps_mm, dtype=float))
    return start + offsets[:, None] * np.ones_like(start)


def minimum_positioning_time(
    steps: Sequence[Sequence[tuple[ArrayLike, ArrayLike]]], *, band_mm: float, hysteresis_mm: float = 0.0
) -> MinimumPositioningTime:
    """Positioning time of each step of the clause 9 sequence (ISO 9283 9: conditions [N], definition [U]).

    The time from leaving one pose until the robot is stabilised at the next, inside the limit band B (0.1, 0.5 or
    1.0 mm for comparison tests [N]). For one step's time series p(t), starting at rest at p(t_0):

    .. math::

        t_{leave} = \\min\\{t : \\lVert p(t) - p(t_0) \\rVert > B\\}, \\qquad
        t_{pos} = t_2 - t_{leave}

    with t_2 the time from which p stays within B + h of its settled (last) position, as in
    :func:`~bench.metrology.iso9283_dynamics.position_stabilisation`. Reported per step as the mean over the
    cycles (n = 3 [N]) and the maximum.

    Parameters
    ----------
    steps : sequence over steps of sequence over cycles of (t_s, position_mm)
        Per step and cycle, the samples from rest at the previous pose to rest at the next: times (m,) in s,
        positions (m, d) in mm. Every step needs the same number of cycles.
    band_mm : float
        Limit band B (mm), > 0.
    hysteresis_mm : float
        Instrument hysteresis h (mm), see :func:`position_stabilisation`.

    Raises
    ------
    InsufficientData
        No step, a series that never leaves the start band or never settles, or a step no longer than 2 B (the
        start and end bands overlap: the time would read negative).

    Examples
    --------
    One step of 2 mm at 10 mm/s, one overshoot sample, then at rest:

    >>> t = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    >>> x = [[0.0], [0.0], [1.0], [2.2], [2.0], [2.0]]
    >>> minimum_positioning_time([[(t, x)]], band_mm=0.1).mean_time_s
    (0.2,)
    """
    require_count("positioning steps", len(steps), 1)
    if not band_mm > 0:
        raise ConfigError(f"band_mm = {band_mm}, expected a number > 0")
    cycles = {len(step) for step in steps}
    if len(cycles) != 1:
        raise ConfigError(f"positioning steps: cycles per step {sorted(cycles)}, expected the same for every step")
    times, distances = [], []
    for i, step in enumerate(steps):
        require_count(f"positioning step {i + 1} cycles", len(step), 1)
        per_cycle, per_distance = [], []
        for j, (t, p) in enumerate(step):
            series_t = as_series(f"step {i + 1} cycle {j + 1} t_s", t, min_count=2)
            series_p = as_points(f"step {i + 1} cycle {j + 1} position_mm", p)
            require_same_length("t_s", series_t, "position_mm", series_p)
            moved = np.flatnonzero(np.linalg.norm(series_p - series_p[0], axis=1) > band_mm)
            if len(moved) == 0:
                raise InsufficientData(
                    f"positioning step {i + 1} cycle {j + 1}: never leaves the {band_mm:g} mm band of its start pose"
                )
            step_mm = float(np.linalg.norm(series_p[-1] - series_p[0]))
            if step_mm <= 2.0 * band_mm:
                # The start and end bands overlap: the robot is "stabilised" before it has left, and t_2 - t_leave
                # would read as a negative or meaningless time (ISO 9283 9 assumes steps much longer than B).
                raise InsufficientData(
                    f"positioning step {i + 1} cycle {j + 1}: the step ({step_mm:.3g} mm) is "
                    f"no longer than twice the {band_mm:g} mm band, so its start and end bands "
                    "overlap and the positioning time is undefined; use a smaller band"
                )
            settled = position_stabilisation(series_t, series_p, band_mm=band_mm, hysteresis_mm=hysteresis_mm)
            per_cycle.append(float(settled.settled_s - series_t[moved[0]]))
            per_distance.append(step_mm)
        times.append(tuple(per_cycle))
        distances.append(float(np.mean(per_distance)))
    return MinimumPositioningTime(
        mean_time_s=tuple(float(np.mean(c)) for c in times),
        max_time_s=tuple(float(np.max(c)) for c in times),
        time_s_per_cycle=tuple(times),
        step_distance_mm=tuple(distances),
        band_mm=float(band_mm),
        n=cycles.pop(),
    )
