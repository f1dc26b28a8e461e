"""The figures of a stored ISO 9283 path run (``iso9283_path``, ``iso9283_cornering``), from its raw streamed samples.

The commanded paths come from the run's stored configuration (the design the protocol stored with it: each path, its
segment targets and the rated path velocity; :class:`PathDesign`), the
attained paths from the ``path`` samples: per cycle, the series of its segments (``raw["series"]``, times relative
to ``raw["t_request_s"]``) joined in step order on the instrument's clock. Every figure is computed by
`bench.metrology`:

- AT_p, RT_p (8.2, 8.3): `path_characteristics` at stations every ``station_mm`` along the path, leaving out
  :data:`~bench.reports.path_cycles.END_MARGIN_MM` at the path's start and end (the robot starts and stops there at rest) and ``margin_mm``
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

from dataclasses import dataclass, field

import numpy as np

from bench.errors import ConfigError, InsufficientData
from bench.metrology import (
    Measured,
    cornering_deviations,
    path_velocity_characteristics,
)
from bench.metrology.formatting import format_length, format_measured
from bench.metrology.iso9283_dynamics import crossing_characteristics
from bench.metrology.path_geometry import CommandedPath
from bench.metrology.uncertainty import instrument_budget, speed_instrument_budget
from bench.metrology.uncertainty_figures import (
    PATH_U_MIN_CYCLES,
    mean_speed_uncertainty,
    path_uncertainty,
    spread_uncertainty,
)
from bench.reports.instrument import (
    INSTRUMENT_SOURCE,
    InstrumentInfo,
    ap_instrument_u_mm,
    calibration_scale_relative_u,
    calibrations_in_force,
    counts_instrument,
    registration_span_mm,
)
from bench.reports.path_cycles import (
    PLOTTED_CYCLES,
    CycleReduction,
    PathCycles,
    attained_cycles,
    path_stations,
    speed_readings,
)
from bench.store import CalibrationRecord, RunRecord, Store

__all__ = [
    "PATH_PROTOCOLS",
    "PLOTTED_CYCLES",
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
    #: (shape, velocity_pct) -> list of (t_s (k,), position_mm (k, 3)) per cycle in cycle order, the first
    #: :data:`~bench.reports.path_cycles.PLOTTED_CYCLES` cycles (the figure's)
    cycles: dict
    #: the instrument's place in U(AT_p), U(RT_p) and in U(AV), worded as ``bench analyze path|path-velocity`` do
    budget: str = ""
    speed_budget: str = ""
    #: (shape, velocity_pct) -> the cycles the run holds (complete or not; ``cycles`` holds the first ones)
    cycle_counts: dict = field(default_factory=dict)
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
    """The figures of every path and velocity of path run ``run_id`` (module docstring), its ``path`` samples
    (``samples`` when the caller has them) read one at a time and reduced cycle by cycle
    (:class:`bench.reports.path_cycles.PathCycles`): the memory of a cycle, not of the run.

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
    reach_mm: float | None = None  # the largest distance from the registration: a scale error's lever arm

    def lever_arm(points: np.ndarray) -> None:
        nonlocal reach_mm
        span = registration_span_mm(run, points)
        if span is not None:
            reach_mm = span if reach_mm is None else max(reach_mm, span)

    cycles = PathCycles(
        protocol,
        station_mm=station_mm,
        margin_mm=margin_mm,
        speed_station_mm=speed_station_mm,
        on_points=lever_arm,
    )
    for sample in read(run_id, kind="path") if samples is None else samples:
        cycles.add(sample)
    instrument = path_instrument(run, calibrations_in_force(store, run), reach_mm)
    u_mm = ap_instrument_u_mm(instrument.sigma_mm, run)  # AT's instrument term: reading, scale, registration
    speed_u_pct, speed_source = speed_scale_u_pct(run)
    figures = []
    for shape, velocity in sorted(cycles.keys, key=lambda key: (key[0], -key[1])):
        complete = cycles.complete((shape, velocity))
        if len(complete) < 2:
            raise InsufficientData(
                f"run {run_id}: {shape} at {velocity:g} %: {len(complete)} complete cycle(s), expected at least 2"
            )
        figures.append(
            _figures(protocol, shape, velocity, complete, cycles.keys[(shape, velocity)].stations, u_mm, speed_u_pct)
        )
    if not figures:
        raise InsufficientData(f"run {run_id}: no path samples")
    return PathRun(
        run_id,
        run.protocol_name,
        protocol,
        tuple(figures),
        cycles.plotted(),
        instrument_budget(u_mm, INSTRUMENT_SOURCE),
        speed_instrument_budget(speed_u_pct, speed_source),
        cycle_counts=cycles.cycle_counts(),
        instrument=instrument,
    )


def _figures(
    protocol: PathDesign,
    shape: str,
    velocity: float,
    complete: list[CycleReduction],
    stations: np.ndarray,
    u_mm: float | None,
    speed_u_pct: float | None,
) -> PathFigures:
    """One path and velocity's figures from its complete cycles' reductions (at least 2)."""
    missed = [(c.missed_station, j) for j, c in enumerate(complete) if c.missed_station is not None]
    if missed:  # as station_crossings: the first station, then the first cycle
        station, j = min(missed)
        raise InsufficientData(f"path cycle {j} never crosses the plane of station {station}")
    crossings = np.stack([c.crossings_mm for c in complete], axis=1)  # (m stations, n cycles, 3)
    r = crossing_characteristics(crossings, stations)
    v_c = protocol.rated_mm_s * velocity / 100.0
    extra: dict = {}
    if len(complete) >= PATH_U_MIN_CYCLES:  # as bench analyze path: the path model over the crossings
        u = path_uncertainty(crossings, stations, instrument_u_mm=u_mm or 0.0)
        extra.update(at_u=u.at, rt_u=u.rt)
    if shape == "rectangle":
        extra["corners"] = _corners(complete, protocol.path(shape))
    if shape == "line":
        errors = [c.speed_error for c in complete if c.speed_error is not None]
        if errors:
            raise InsufficientData(errors[0])
        v = path_velocity_characteristics([c.speeds_mm_s for c in complete], v_c)
        extra.update(av_pct=v.av_pct, rv_pct=v.rv_pct, fv_mm_s=v.fv_mm_s, mean_speed_mm_s=v.mean_speed_mm_s)
        # a speed read by the mice carries their scale's relative u (the calibration in force), else U(AV) says
        # it has none, as bench analyze path-velocity does
        extra["av_u"] = mean_speed_uncertainty(
            v.av_pct, v.mean_speed_per_cycle_mm_s, v_c, instrument_u_pct=speed_u_pct or 0.0
        )
        extra["rv_u"] = spread_uncertainty(v.rv_pct, v.n, unit="%")
    return PathFigures(
        shape,
        velocity,
        v_c,
        len(complete),
        protocol.n_segments(shape),
        r.at_mm,
        r.rt_mm,
        len(stations),
        duration_s=float(np.mean([c.duration_s for c in complete])),
        **extra,
    )


def _corners(complete: list[CycleReduction], path) -> tuple[tuple[str, float, float], ...]:
    """CR, CO at P3, P4, P5 over each cycle's samples near the corner (module docstring)."""
    out = []
    vertices = path.vertices_mm
    for index, (number, label) in enumerate(((1, "P3"), (2, "P4"), (3, "P5"))):
        corner, before, after = vertices[number], vertices[number - 1], vertices[number + 1]
        r = cornering_deviations([c.near_corners[index] for c in complete], corner, before, after)
        out.append((label, r.cr_mm, r.co_mm))
    return tuple(out)


def speed_scale_u_pct(run: RunRecord) -> tuple[float | None, str]:
    """The relative standard uncertainty (%) of a speed the run's counts instrument reads (its calibration scale in
    force: a speed is a length per time), and its source; None when the run stored no scale calibration."""
    calibration = (run.settings.get("instrument") or {}).get("scale_calibration")
    if not isinstance(calibration, dict):
        return None, INSTRUMENT_SOURCE
    relative, why = calibration_scale_relative_u(calibration)
    return 100.0 * relative, f"the calibration in force, {why}"


def path_instrument(
    run: RunRecord, calibrations: tuple[CalibrationRecord, ...], span_mm: float | None
) -> InstrumentInfo:
    """The run's counts instrument (:func:`bench.reports.instrument.counts_instrument`) with the scale of the
    calibration in force at ``span_mm``, the largest distance the attained paths reach from the registration, as a pose report
    has it: a scale error moves every attained point by its distance from the registration, which AT_p carries."""
    return counts_instrument(run, calibrations, 0, span_mm=span_mm)
