"""A path run's ``path`` samples reduced cycle by cycle as they are read: memory by the cycle, not the run.

Every figure of :func:`bench.reports.path_run.analyze_path_run` needs each cycle only through a few numbers, so a
cycle's samples are joined (:func:`join_segments`) once its last segment is read, reduced, and dropped:

- AT_p, RT_p (ISO 9283 8.2, 8.3) and their U: the cycle's crossing of every station plane
  (:func:`bench.metrology.iso9283_dynamics.cycle_crossings`, the numbers ``station_crossings`` gives that cycle);
- CR, CO (8.5): the cycle's samples within :data:`CORNER_RADIUS_MM` of each corner, in its pass closest to it;
- AV, RV, FV (8.6): the cycle's speed samples over the constant-velocity part (:func:`speed_readings`);
- the mean cycle time: the cycle's duration.

What is kept per cycle is a few kB (3 floats per station), against about 100 bytes a streamed point; the figure of
the attained paths keeps the first :data:`PLOTTED_CYCLES` cycles of each path and velocity. The figures equal those
of the whole run held at once (``tests/test_reports_path_stream.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.errors import ConfigError, InsufficientData
from bench.metrology import path_speed
from bench.metrology.iso9283_dynamics import cycle_crossings

__all__ = [
    "END_MARGIN_MM",
    "PLOTTED_CYCLES",
    "CycleReduction",
    "PathCycles",
    "attained_cycles",
    "join_segments",
    "path_stations",
    "speed_readings",
]

#: No AT station this close to a path's start or end (mm) [P].
END_MARGIN_MM = 5.0
#: CR, CO read the attained samples this close to a corner (mm), in the pass that comes closest.
CORNER_RADIUS_MM = 5.0
#: Cycles of each path and velocity drawn in the report's figure (ISO 9283 Table 5: 10 cycles; more overlap unread).
PLOTTED_CYCLES = 10


def sample_series(sample) -> tuple[np.ndarray, np.ndarray]:
    """A ``path`` sample's streamed series as (t_s (k,) on the instrument's clock, position_mm (k, 3))."""
    series = sample.raw.get("series") if isinstance(sample.raw, dict) else None
    if not series or "t_request_s" not in sample.raw:
        raise InsufficientData(
            f"sample at step {sample.step_index}: no streamed series with its start time, "
            "expected a path segment captured by a streaming instrument"
        )
    t = float(sample.raw["t_request_s"]) + np.asarray(series["t_s"], float)
    return t, np.column_stack([np.asarray(series[a], float) for a in ("x_mm", "y_mm", "z_mm")])


def join_segments(parts: list) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """One cycle from its segments ``(step_index, t_s, position_mm)``: joined in step order, a point not later than
    the one before (a window reaching back into the previous segment) dropped, so times strictly increase; returns
    (t_s, position_mm, segment start indices)."""
    times, points, starts, last, joined = [], [], [], -np.inf, 0
    for _, t, p in sorted(parts, key=lambda part: part[0]):
        keep = t > last
        starts.append(joined)
        times.append(t[keep])
        joined += len(times[-1])
        points.append(p[keep])
        if keep.any():
            last = float(t[keep][-1])
    return np.concatenate(times), np.concatenate(points), starts


def attained_cycles(samples) -> dict[tuple[str, float], list[tuple[int, np.ndarray, np.ndarray, list[int]]]]:
    """Per (shape, velocity_pct): per cycle (cycle, t_s, position_mm, segment start indices), from ``path`` samples
    (:func:`join_segments`), every cycle held: for a short run (a test's); the analysis reduces as it reads
    (:class:`PathCycles`)."""
    grouped: dict[tuple[str, float, int], list] = {}
    for s in samples:
        grouped.setdefault((s.pose, float(s.values["velocity_pct"]), int(s.cycle)), []).append(
            (s.step_index, *sample_series(s))
        )
    out: dict = {}
    for (shape, velocity, cycle), parts in sorted(grouped.items()):
        out.setdefault((shape, velocity), []).append((cycle, *join_segments(parts)))
    return out


def path_stations(path, spacing_mm: float, margin_mm: float, end_margin_mm: float = END_MARGIN_MM) -> np.ndarray:
    """Stations every ``spacing_mm``, at least ``end_margin_mm`` from the path's start and end (where every cycle
    starts and stops at rest, and an attained start past the first plane never crosses it) and ``margin_mm`` from
    the rectangle's corners."""
    s = np.arange(spacing_mm / 2, path.length_mm, spacing_mm)
    s = s[(s >= end_margin_mm) & (s <= path.length_mm - end_margin_mm)]
    if path.shape == "rectangle":
        edges = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path.vertices_mm, axis=0), axis=1))])
        s = s[np.min(np.abs(s[:, None] - edges[None, :]), axis=1) >= margin_mm]
    return path.point(s)


def _speed_reading(t: np.ndarray, p: np.ndarray, spacing_mm: float, step_s: float, hold_s: float):
    start, end = t[0], t[-1] - hold_s
    grid = np.arange(start + 0.1 * (end - start), start + 0.9 * (end - start) + 1e-9, step_s)
    if len(grid) < 3:
        raise InsufficientData(
            f"path velocity: {len(grid)} speed samples per cycle, expected a longer line "
            f"than {spacing_mm:g} mm steps allow"
        )
    return grid, np.column_stack([np.interp(grid, t, p[:, axis]) for axis in range(p.shape[1])])


def speed_readings(
    cycles, spacing_mm: float, commanded_mm_s: float, hold_s: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The constant-velocity part of every cycle as ``bench analyze path-velocity`` reads it: per cycle (t_s (k,),
    position_mm (k, 3)), the attained path read at times ``spacing_mm / v_c`` apart (linear between samples) over the
    middle 80 % of the motion's time; its speeds are :func:`bench.metrology.path_speed`."""
    step_s = spacing_mm / commanded_mm_s
    return [_speed_reading(t, p, spacing_mm, step_s, hold_s) for _, t, p, _ in cycles]


def near_corner(p: np.ndarray, corner: np.ndarray) -> np.ndarray:
    """The samples of one cycle within :data:`CORNER_RADIUS_MM` of ``corner`` in the pass that comes closest (one
    pass per cycle), a copy (the cycle's arrays are dropped)."""
    distance = np.linalg.norm(p - corner, axis=1)
    closest = int(np.argmin(distance))
    inside = distance < CORNER_RADIUS_MM
    lo, hi = closest, closest
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    while hi < len(p) - 1 and inside[hi + 1]:
        hi += 1
    return p[lo : hi + 1].copy()


@dataclass(frozen=True, eq=False)
class CycleReduction:
    """What the figures need of one complete cycle (module docstring)."""

    cycle: int
    duration_s: float
    crossings_mm: np.ndarray  #: (m stations, 3); NaN rows from ``missed_station`` on where the path never crosses
    missed_station: int | None
    near_corners: tuple[np.ndarray, ...] = ()  #: rectangle: the samples near P3, P4, P5
    speeds_mm_s: np.ndarray | None = None  #: line: the speed samples of 8.6
    speed_error: str | None = None  #: line: why it has none


@dataclass(eq=False)
class _Key:
    """One path and velocity's cycles while the run is read."""

    stations: np.ndarray
    n_segments: int
    open: dict[int, list] = field(default_factory=dict)  #: cycle -> its segments read so far
    reduced: dict[int, CycleReduction] = field(default_factory=dict)
    spoiled: set[int] = field(default_factory=set)  #: cycles with more segments than the path has (incomplete)
    plotted: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    seen: set[int] = field(default_factory=set)

    def plot(self, cycle: int, t: np.ndarray, p: np.ndarray) -> None:
        self.plotted[cycle] = (t, p)
        if len(self.plotted) > PLOTTED_CYCLES:
            del self.plotted[max(self.plotted)]


class PathCycles:
    """Reads a path run's samples one at a time (:meth:`add`) and keeps each complete cycle's reduction.

    A cycle is complete with as many segments as its path has (``design.n_segments``); its reduction is made when
    its last segment is read, whatever the order of the segments, and undone should a further segment of it come.
    """

    def __init__(
        self,
        design,
        *,
        station_mm: float,
        margin_mm: float,
        speed_station_mm: float,
        on_points: Callable[[np.ndarray], None] | None = None,
    ) -> None:
        self.design = design
        #: called with every sample's attained points (k, 3) as they are read (e.g. their reach from a registration)
        self.on_points = on_points
        self.station_mm, self.margin_mm, self.speed_station_mm = station_mm, margin_mm, speed_station_mm
        self.keys: dict[tuple[str, float], _Key] = {}

    def add(self, sample) -> None:
        shape, velocity, cycle = sample.pose, float(sample.values["velocity_pct"]), int(sample.cycle)
        t, p = sample_series(sample)
        if self.on_points is not None:
            self.on_points(p)
        key = self.keys.get((shape, velocity))
        if key is None:
            if shape not in self.design.paths:
                raise ConfigError(
                    f"sample at step {sample.step_index}: path {shape!r}, expected one of the run's stored paths "
                    f"({', '.join(self.design.shapes)})"
                )
            stations = path_stations(self.design.path(shape), self.station_mm, self.margin_mm)
            key = self.keys[(shape, velocity)] = _Key(stations, self.design.n_segments(shape))
        key.seen.add(cycle)
        if cycle in key.spoiled:
            return
        if cycle in key.reduced:  # a segment more than the path has: not a complete cycle
            del key.reduced[cycle]
            key.plotted.pop(cycle, None)
            key.spoiled.add(cycle)
            return
        parts = key.open.setdefault(cycle, [])
        parts.append((sample.step_index, t, p))
        if len(parts) == key.n_segments:
            del key.open[cycle]
            t, p, _ = join_segments(parts)
            key.reduced[cycle] = self._reduce(shape, velocity, cycle, key.stations, t, p)
            key.plot(cycle, t, p)

    def _reduce(self, shape: str, velocity: float, cycle: int, stations, t, p) -> CycleReduction:
        crossings, missed = cycle_crossings(p, stations)
        extra: dict[str, Any] = {}
        path = self.design.path(shape)
        if shape == "rectangle":
            extra["near_corners"] = tuple(near_corner(p, path.vertices_mm[n]) for n in (1, 2, 3))
        if shape == "line":
            v_c = self.design.rated_mm_s * velocity / 100.0
            try:
                step_s = self.speed_station_mm / v_c
                extra["speeds_mm_s"] = path_speed(
                    *_speed_reading(t, p, self.speed_station_mm, step_s, self.design.final_hold_s)
                )
            except InsufficientData as error:
                extra["speed_error"] = str(error)
        return CycleReduction(cycle, t[-1] - t[0], crossings, missed, **extra)

    def complete(self, key: tuple[str, float]) -> list[CycleReduction]:
        """The complete cycles of one path and velocity, in cycle order."""
        reduced = self.keys[key].reduced
        return [reduced[c] for c in sorted(reduced)]

    def plotted(self) -> dict[tuple[str, float], list[tuple[np.ndarray, np.ndarray]]]:
        """Per path and velocity, (t_s, position_mm) of its first :data:`PLOTTED_CYCLES` cycles (the incomplete
        ones included, as read), in cycle order."""
        for key in self.keys.values():
            for cycle, parts in key.open.items():
                key.plot(cycle, *join_segments(parts)[:2])
        return {k: [key.plotted[c] for c in sorted(key.plotted)] for k, key in self.keys.items()}

    def cycle_counts(self) -> dict[tuple[str, float], int]:
        """Per path and velocity, how many cycles the run holds (complete or not)."""
        return {k: len(key.seen) for k, key in self.keys.items()}
