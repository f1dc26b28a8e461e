"""The figures of a stored ISO 9283 path run (``iso9283_path``, ``iso9283_cornering``), from its raw streamed samples.

The commanded paths come from the run's stored configuration (the design the protocol stored with it: each path, its
segment targets and the rated path velocity; :class:`PathDesign`), the
attained paths from the ``path`` samples: per cycle, the series of its segments (``raw["series"]``, times relative
to ``raw["t_request_s"]``) joined in step order on the instrument's clock. Every figure is computed by
`bench.metrology`:

- AT_p, RT_p (8.2, 8.3): `path_characteristics` at stations every ``station_mm`` along the path, leaving out
  :data:`END_MARGIN_MM` at the path's start and end (the robot starts and stops there at rest) and ``margin_mm``
  about the rectangle's corners (there the plane normal to the path is not defined, and cornering is its own
  test) [P];
- CR, CO (8.5): `cornering_deviations` at the rectangle's corners P3, P4, P5 (P2, where every cycle starts and ends
  at rest, is not a corner passed through) over the samples of the segments next to the corner;
- AV, RV, FV (8.6): on the line, `path_velocity_characteristics` of speed samples v_i = |p(t_i + dt) - p(t_i)| / dt,
  dt = ``speed_station_mm`` / v_c, over the middle 80 % of the time of the motion (the constant-velocity part) [P];
  the attained path is read between its samples linearly. With an instrument of resolution r each speed sample
  carries a quantisation of about r / speed_station_mm (1.6 % for 800 cpi mice and 2 mm), which enters FV.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.errors import ConfigError, InsufficientData
from bench.metrology import (
    Measured,
    cornering_deviations,
    path_characteristics,
    path_speed,
    path_velocity_characteristics,
)
from bench.metrology.formatting import format_length, format_measured
from bench.metrology.iso9283_dynamics import station_crossings
from bench.metrology.path_geometry import CommandedPath
from bench.metrology.uncertainty import instrument_budget, speed_instrument_budget
from bench.metrology.uncertainty_figures import (
    PATH_U_MIN_CYCLES,
    mean_speed_uncertainty,
    path_uncertainty,
    spread_uncertainty,
)
from bench.reports.content import INSTRUMENT_SOURCE, calibrations_in_force
from bench.reports.instrument import (
    InstrumentInfo,
    ap_instrument_u_mm,
    calibration_scale_relative_u,
    counts_instrument,
    registration_span_mm,
)
from bench.store import CalibrationRecord, RunRecord, Store

__all__ = [
    "PATH_PROTOCOLS",
    "PathDesign",
    "PathFigures",
    "PathRun",
    "analyze_path_run",
    "attained_cycles",
    "figure_text",
    "path_stations",
    "speed_readings",
]

PATH_PROTOCOLS = ("iso9283_path", "iso9283_cornering")

#: No AT station this close to a path's start or end (mm) [P].
END_MARGIN_MM = 5.0


@dataclass(frozen=True)
class PathFigures:
    """The figures of one path at one velocity."""

    shape: str
    velocity_pct: float
    commanded_mm_s: float
    n_cycles: int
    n_segments: int
    at_mm: float
    rt_mm: float
    n_stations: int
    #: per corner label (P3, P4, P5): (CR_mm, CO_mm); empty unless a rectangle
    corners: tuple[tuple[str, float, float], ...] = ()
    av_pct: float | None = None
    rv_pct: float | None = None
    fv_mm_s: float | None = None
    mean_speed_mm_s: float | None = None
    duration_s: float = 0.0  #: mean attained time of one cycle, s
    #: AT_p, RT_p with U (k = 2, path-model Monte Carlo); None with fewer than :data:`PATH_U_MIN_CYCLES` cycles
    at_u: Measured | None = None
    rt_u: Measured | None = None
    av_u: Measured | None = None  #: AV with U (Student's k at ν_eff), on the line
    rv_u: Measured | None = None  #: RV with U (chi pivot, k = 2), on the line

    def as_json(self) -> dict:
        out = {
            "shape": self.shape,
            "velocity_pct": self.velocity_pct,
            "commanded_mm_s": self.commanded_mm_s,
            "n_cycles": self.n_cycles,
            "n_segments": self.n_segments,
            "n_stations": self.n_stations,
            "AT_mm": self.at_mm,
            "RT_mm": self.rt_mm,
            "cycle_duration_s": self.duration_s,
            "U_AT_mm": None if self.at_u is None else self.at_u.expanded_uncertainty,
            "U_RT_mm": None if self.rt_u is None else self.rt_u.expanded_uncertainty,
        }
        if self.corners:
            out["corners"] = [{"corner": c, "CR_mm": cr, "CO_mm": co} for c, cr, co in self.corners]
            out["CR_mm"] = max(cr for _, cr, _ in self.corners)
            out["CO_mm"] = max(co for _, _, co in self.corners)
        if self.av_pct is not None:
            out.update(
                {
                    "AV_pct": self.av_pct,
                    "RV_pct": self.rv_pct,
                    "FV_mm_s": self.fv_mm_s,
                    "mean_speed_mm_s": self.mean_speed_mm_s,
                    "U_AV_pct": None if self.av_u is None else self.av_u.expanded_uncertainty,
                    "k_AV": None if self.av_u is None else self.av_u.coverage_factor,
                    "U_RV_pct": None if self.rv_u is None else self.rv_u.expanded_uncertainty,
                }
            )
        return out


@dataclass(frozen=True, eq=False)
class PathRun:
    """Every path and velocity of one run, with the commanded paths and the attained cycles (for the figure)."""

    run_id: int
    protocol_name: str
    design: PathDesign  #: the commanded paths, as stored with the run
    figures: tuple[PathFigures, ...]
    #: (shape, velocity_pct) -> list of (t_s (k,), position_mm (k, 3)) per cycle in cycle order
    cycles: dict
    #: the instrument's place in U(AT_p), U(RT_p) and in U(AV), worded as ``bench analyze path|path-velocity`` do
    budget: str = ""
    speed_budget: str = ""
    #: the instrument as its U(AT_p) term was made (the report's budget table)
    instrument: InstrumentInfo | None = None


def figure_text(value: float | None, measured: Measured | None, *, signed: bool = False, none: str = "—") -> str:
    """A path figure as ``bench analyze path|path-velocity`` print it: ``value ± U`` rounded by U (one rule,
    :func:`bench.metrology.formatting.format_measured`), to 1 µm without a U (fewer cycles than the path model
    needs), ``none`` where the path has no such figure."""
    if value is None:
        return none
    if measured is None:
        return format_length(value, signed=signed)
    return format_measured(measured.value, measured.expanded_uncertainty, signed=signed)


def attained_cycles(samples) -> dict[tuple[str, float], list[tuple[int, np.ndarray, np.ndarray, list[int]]]]:
    """Per (shape, velocity_pct): per cycle (cycle, t_s, position_mm, segment start indices), from ``path`` samples.

    Samples of a cycle are joined in step order; a point not later than the one before (a window reaching back
    into the previous segment) is dropped, so times strictly increase."""
    grouped: dict[tuple[str, float, int], list] = {}
    for s in samples:  # each sample's series kept as arrays only: the parsed JSON is dropped as it is read
        series = s.raw.get("series") if isinstance(s.raw, dict) else None
        if not series or "t_request_s" not in s.raw:
            raise InsufficientData(
                f"sample at step {s.step_index}: no streamed series with its start time, "
                "expected a path segment captured by a streaming instrument"
            )
        t = float(s.raw["t_request_s"]) + np.asarray(series["t_s"], float)
        p = np.column_stack([np.asarray(series[a], float) for a in ("x_mm", "y_mm", "z_mm")])
        grouped.setdefault((s.pose, float(s.values["velocity_pct"]), int(s.cycle)), []).append((s.step_index, t, p))
    out: dict = {}
    for (shape, velocity, cycle), parts in sorted(grouped.items()):
        times, points, starts, last = [], [], [], -np.inf
        for _, t, p in sorted(parts, key=lambda part: part[0]):
            keep = t > last
            starts.append(sum(len(x) for x in times))
            times.append(t[keep])
            points.append(p[keep])
            if keep.any():
                last = float(t[keep][-1])
        out.setdefault((shape, velocity), []).append((cycle, np.concatenate(times), np.concatenate(points), starts))
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


def speed_readings(
    cycles, spacing_mm: float, commanded_mm_s: float, hold_s: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The constant-velocity part of every cycle as ``bench analyze path-velocity`` reads it (module docstring): per
    cycle (t_s (k,), position_mm (k, 3)), the attained path read at times ``spacing_mm / v_c`` apart (linear between
    samples) over the middle 80 % of the motion's time; its speeds are :func:`bench.metrology.path_speed`."""
    step_s = spacing_mm / commanded_mm_s
    readings = []
    for _, t, p, _ in cycles:
        start, end = t[0], t[-1] - hold_s
        grid = np.arange(start + 0.1 * (end - start), start + 0.9 * (end - start) + 1e-9, step_s)
        if len(grid) < 3:
            raise InsufficientData(
                f"path velocity: {len(grid)} speed samples per cycle, expected a longer line "
                f"than {spacing_mm:g} mm steps allow"
            )
        readings.append((grid, np.column_stack([np.interp(grid, t, p[:, axis]) for axis in range(p.shape[1])])))
    return readings


def _corners(cycles, path) -> tuple[tuple[str, float, float], ...]:
    """CR, CO at P3, P4, P5 over the segments next to each corner (module docstring)."""
    out = []
    vertices = path.vertices_mm
    for number, label in ((1, "P3"), (2, "P4"), (3, "P5")):
        corner, before, after = vertices[number], vertices[number - 1], vertices[number + 1]
        near = []
        for _, _, p, _ in cycles:
            distance = np.linalg.norm(p - corner, axis=1)
            # the attained samples within 5 mm of the corner, in the pass that comes closest (one pass per cycle)
            closest = int(np.argmin(distance))
            inside = distance < 5.0
            lo, hi = closest, closest
            while lo > 0 and inside[lo - 1]:
                lo -= 1
            while hi < len(p) - 1 and inside[hi + 1]:
                hi += 1
            near.append(p[lo : hi + 1])
        r = cornering_deviations(near, corner, before, after)
        out.append((label, r.cr_mm, r.co_mm))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class PathDesign:
    """What a path run commanded, read back from its stored configuration (``paths``, ``rated_path_speed_mm_s``,
    ``chord_error_mm``, ``final_hold_s``): the paths as :class:`bench.metrology.path_geometry.CommandedPath`."""

    paths: dict  #: shape -> CommandedPath, in the order driven
    segment_targets_mm: dict  #: shape -> (n + 1, 3) the start and every segment's end
    max_chord_error_mm: dict  #: shape -> the largest joint-space chord error of its segments
    rated_mm_s: float
    chord_error_mm: float
    final_hold_s: float

    @property
    def shapes(self) -> tuple[str, ...]:
        return tuple(self.paths)

    def path(self, shape: str) -> CommandedPath:
        return self.paths[shape]

    def n_segments(self, shape: str) -> int:
        return len(self.segment_targets_mm[shape]) - 1

    @classmethod
    def from_config(cls, config: dict, source: str) -> PathDesign:
        missing = [k for k in ("paths", "rated_path_speed_mm_s", "chord_error_mm", "final_hold_s") if k not in config]
        if missing:
            raise ConfigError(
                f"{source}: not stored: config.{', config.'.join(missing)} (a path run stores its "
                "commanded paths), expected a run made by this version's path protocols"
            )
        paths, targets, chords = {}, {}, {}
        for stored in config["paths"]:
            shape = stored["shape"]
            paths[shape] = CommandedPath(
                shape,
                np.asarray(stored["vertices_mm"], float).reshape(-1, 3),
                np.asarray(stored["centre_mm"], float),
                float(stored["radius_mm"]),
                np.asarray(stored["u"], float),
                np.asarray(stored["v"], float),
            )
            targets[shape] = np.asarray(stored["segment_targets_mm"], float)
            chords[shape] = float(stored["max_chord_error_mm"])
        return cls(
            paths,
            targets,
            chords,
            float(config["rated_path_speed_mm_s"]),
            float(config["chord_error_mm"]),
            float(config["final_hold_s"]),
        )


def analyze_path_run(
    store: Store,
    run_id: int,
    *,
    station_mm: float = 1.0,
    margin_mm: float = 2.0,
    speed_station_mm: float = 2.0,
    samples=None,
) -> PathRun:
    """The figures of every path and velocity of path run ``run_id`` (module docstring); ``samples``: its ``path``
    samples when the caller has read them already (a report reads them once).

    Raises
    ------
    ConfigError
        When the run is not a path run.
    InsufficientData
        When it has fewer than two complete cycles of a path and velocity (an aborted run: the cycles it finished).
    """
    run = store.run(run_id)
    if run.protocol_name not in PATH_PROTOCOLS:
        raise ConfigError(f"run {run_id}: a {run.protocol_name} run, expected one of {', '.join(PATH_PROTOCOLS)}")
    protocol = PathDesign.from_config(run.config, source=f"run {run_id}")
    read = getattr(store, "iter_samples", store.samples)  # a sample at a time where the store can (lab views: a list)
    grouped = attained_cycles(read(run_id, kind="path") if samples is None else samples)
    instrument = path_instrument(run, calibrations_in_force(store, run), grouped)
    u_mm = ap_instrument_u_mm(instrument.sigma_mm, run)  # AT's instrument term: reading, scale, registration
    speed_u_pct, speed_source = speed_scale_u_pct(run)
    figures = []
    for (shape, velocity), cycles in sorted(grouped.items(), key=lambda item: (item[0][0], -item[0][1])):
        n_segments = protocol.n_segments(shape)
        complete = [c for c in cycles if len(c[3]) == n_segments]
        if len(complete) < 2:
            raise InsufficientData(
                f"run {run_id}: {shape} at {velocity:g} %: {len(complete)} complete cycle(s), expected at least 2"
            )
        path = protocol.path(shape)
        stations = path_stations(path, station_mm, margin_mm)
        attained = [p for _, _, p, _ in complete]
        r = path_characteristics(attained, stations)
        v_c = protocol.rated_mm_s * velocity / 100.0
        extra: dict = {}
        if len(complete) >= PATH_U_MIN_CYCLES:  # as bench analyze path: the path model over the crossings
            u = path_uncertainty(station_crossings(attained, stations)[0], stations, instrument_u_mm=u_mm or 0.0)
            extra.update(at_u=u.at, rt_u=u.rt)
        if shape == "rectangle":
            extra["corners"] = _corners(complete, path)
        if shape == "line":
            readings = speed_readings(complete, speed_station_mm, v_c, protocol.final_hold_s)
            v = path_velocity_characteristics([path_speed(t, p) for t, p in readings], v_c)
            extra.update(av_pct=v.av_pct, rv_pct=v.rv_pct, fv_mm_s=v.fv_mm_s, mean_speed_mm_s=v.mean_speed_mm_s)
            # a speed read by the mice carries their scale's relative u (the calibration in force), else U(AV) says
            # it has none, as bench analyze path-velocity does
            extra["av_u"] = mean_speed_uncertainty(
                v.av_pct, v.mean_speed_per_cycle_mm_s, v_c, instrument_u_pct=speed_u_pct or 0.0
            )
            extra["rv_u"] = spread_uncertainty(v.rv_pct, v.n, unit="%")
        duration = float(np.mean([t[-1] - t[0] for _, t, _, _ in complete]))
        figures.append(
            PathFigures(
                shape,
                velocity,
                v_c,
                len(complete),
                n_segments,
                r.at_mm,
                r.rt_mm,
                len(stations),
                duration_s=duration,
                **extra,
            )
        )
    if not figures:
        raise InsufficientData(f"run {run_id}: no path samples")
    return PathRun(
        run_id,
        run.protocol_name,
        protocol,
        tuple(figures),
        {key: [(t, p) for _, t, p, _ in cycles] for key, cycles in grouped.items()},
        instrument_budget(u_mm, INSTRUMENT_SOURCE),
        speed_instrument_budget(speed_u_pct, speed_source),
        instrument,
    )


def speed_scale_u_pct(run: RunRecord) -> tuple[float | None, str]:
    """The relative standard uncertainty (%) of a speed the run's counts instrument reads (its calibration scale in
    force: a speed is a length per time), and its source; None when the run stored no scale calibration."""
    calibration = (run.settings.get("instrument") or {}).get("scale_calibration")
    if not isinstance(calibration, dict):
        return None, INSTRUMENT_SOURCE
    relative, why = calibration_scale_relative_u(calibration)
    return 100.0 * relative, f"the calibration in force, {why}"


def path_instrument(run: RunRecord, calibrations: tuple[CalibrationRecord, ...], grouped: dict) -> InstrumentInfo:
    """The run's counts instrument (:func:`bench.reports.instrument.counts_instrument`) with the scale of the
    calibration in force at the largest distance the attained paths reach from the registration, as a pose report
    has it: a scale error moves every attained point by its distance from the registration, which AT_p carries."""
    points = [p for cycles in grouped.values() for _, _, p, _ in cycles]
    span = registration_span_mm(run, np.concatenate(points)) if points else None
    return counts_instrument(run, calibrations, 0, span_mm=span)
