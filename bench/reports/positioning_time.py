"""The figures and report of a stored ``iso9283_positioning_time`` run: minimum positioning time (ISO 9283 9).

Every figure comes from :func:`bench.metrology.minimum_positioning_time` on the run's streamed series
(:func:`bench.store.series_table` of kind ``positioning``, the raw-data CSV, = ``bench export RUN --kind positioning
--series``), read per condition (velocity, load) by :func:`bench.metrology.path_tables.positioning_steps`, the call
``bench analyze positioning-time FILE.csv`` makes. For one step's series p(t), from rest at the previous pose p(t_0)
to rest at the next (the protocol streams ``rest_s`` before the move and ``hold_s`` after it):

    t_leave = min{t : |p(t) - p(t_0)| > B},   t_pos = t_2 - t_leave,

t_2 the time from which p stays within B + h of its settled (last) position (as the stabilisation time, 7.4), per
step the mean over the cycles (ISO: 3) and the largest. Only cycles with every step stored are used (an aborted run:
the cycles it finished). Limit bands B (ISO comparison bands 0.1, 0.5, 1.0 mm) and the hysteresis h (one instrument
count by default, as for stabilisation runs: `bench.reports.stabilisation`) are chosen at analysis time.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.metrology import MinimumPositioningTime, minimum_positioning_time
from bench.metrology.path_tables import positioning_steps
from bench.reports.content import ReportBase, calibrations_in_force, provenance, run_table
from bench.reports.criteria import Characteristic, decision_section
from bench.reports.deviations import Deviation, _fmt, _load, _planned_count, _row
from bench.reports.deviations_arrivals import ISO_BANDS_MM
from bench.reports.document import Paragraph, RawData, Table, assemble, conditions_section
from bench.reports.instrument import counts_instrument
from bench.reports.plots import MIN_FONT_PT, Plot, print_grid
from bench.reports.stabilisation import _bands, _hysteresis, count_size_mm
from bench.store import Store

__all__ = [
    "PROTOCOL",
    "PositioningFigures",
    "PositioningRun",
    "PositioningTimeReport",
    "analyze_positioning_run",
    "collect_positioning_time",
    "positioning_time_document",
    "positioning_time_plot",
]

PROTOCOL = "iso9283_positioning_time"
#: ISO 9283 Table 5 [N] and Table 19 [N]: cycles and steps of the test.
CYCLES, TABLE_19_STEPS = 3, 7
SCOPE = (
    "Tested following the method of ISO 9283:1998 clause 9 (minimum positioning time), with the deviations "
    "listed in the deviations table. Results are ISO 9283-style; this is not an ISO 9283 certification."
)
NO_CRITERION = "no acceptance criterion stated: no pass/fail statement (ISO 9283 defines methods, not grades)"
_CONDITIONS = ("velocity_pct", "load_kg")


@dataclass(frozen=True)
class PositioningFigures:
    """The positioning times of one condition (velocity, load) in one limit band, or why there are none."""

    velocity_pct: float
    load_kg: float
    band_mm: float
    steps: tuple[int, ...]  #: Table 19 numbers, in order (result follows it)
    cycles: tuple[int, ...]  #: the complete cycles analysed
    result: MinimumPositioningTime | None
    reason: str = ""

    def as_json(self) -> dict:
        out = {
            "velocity_pct": self.velocity_pct,
            "load_kg": self.load_kg,
            "band_mm": self.band_mm,
            "cycles": list(self.cycles),
        }
        if self.result is None:
            return {**out, "reason": self.reason}
        r = self.result
        return {
            **out,
            "steps": [
                {"step": s, "distance_mm": d, "mean_time_s": mean, "max_time_s": worst, "time_s_per_cycle": list(per)}
                for s, d, mean, worst, per in zip(
                    self.steps, r.step_distance_mm, r.mean_time_s, r.max_time_s, r.time_s_per_cycle
                )
            ],
        }


@dataclass(frozen=True, eq=False)
class PositioningRun:
    """Every condition and band of one run, with the design it commanded and the series (for the figure)."""

    run_id: int
    steps: tuple[dict, ...]  #: the stored design: step, distance_mm, target_mm per step driven
    skipped: tuple[dict, ...]  #: step, target_mm, reason per step the pre-flight left out
    bands_mm: tuple[float, ...]
    hysteresis_mm: float
    hysteresis_source: str
    figures: tuple[PositioningFigures, ...]  #: per condition, then band
    #: (velocity_pct, load_kg) -> step -> list of (cycle, t_s, position_mm) of the complete cycles
    series: dict

    def as_json(self) -> dict:
        return {
            "run_id": self.run_id,
            "hysteresis_mm": self.hysteresis_mm,
            "steps": list(self.steps),
            "skipped_steps": list(self.skipped),
            "results": [f.as_json() for f in self.figures],
        }


def _condition_tables(table: pd.DataFrame):
    """(velocity_pct, load_kg, rows) per condition of a positioning series table, highest velocity first."""
    table = table.assign(**{c: table[c] if c in table.columns else 0.0 for c in _CONDITIONS})
    for (velocity, load), rows in sorted(
        table.groupby(list(_CONDITIONS), sort=False), key=lambda item: (item[0][1], -item[0][0])
    ):
        yield float(velocity), float(load), rows.drop(columns=list(_CONDITIONS))


def analyze_positioning_run(
    store: Store, run_id: int, *, bands_mm=None, hysteresis_mm: float | None = None
) -> PositioningRun:
    """Minimum positioning time of every step, condition and band of run ``run_id`` (module docstring).

    Raises
    ------
    ConfigError
        The run is not an ``iso9283_positioning_time`` run, or a band or the hysteresis is not a number > 0 (>= 0).
    InsufficientData
        No cycle of some condition has every step stored.
    """
    run = store.run(run_id)
    if run.protocol_name != PROTOCOL:
        raise ConfigError(f"run {run_id}: a {run.protocol_name} run, expected an {PROTOCOL} run")
    bands = _bands(bands_mm)
    hysteresis, source = _hysteresis(count_size_mm(run, calibrations_in_force(store, run)), hysteresis_mm)
    design = tuple(run.config.get("steps") or ())
    if not design:
        raise ConfigError(
            f"run {run_id}: not stored: config.steps, expected a run made by this version's {PROTOCOL} protocol"
        )
    planned = {int(s["step"]) for s in design}
    figures, series = [], {}
    for velocity, load, rows in _condition_tables(run_table(store, run_id, "positioning", series=True)):
        complete = sorted(c for c, part in rows.groupby("cycle") if set(part["step"].astype(int)) == planned)
        if not complete:
            raise InsufficientData(
                f"run {run_id}: {velocity:g} %, {load:g} kg: no cycle with all {len(planned)} steps stored"
            )
        numbers, steps = positioning_steps(rows[rows["cycle"].isin(complete)])
        series[(velocity, load)] = {
            n: [(c, t, p) for c, (t, p) in zip(complete, cycles)] for n, cycles in zip(numbers, steps)
        }
        for band in bands:
            try:
                result = minimum_positioning_time(steps, band_mm=band, hysteresis_mm=hysteresis)
                figures.append(PositioningFigures(velocity, load, band, numbers, tuple(complete), result))
            except InsufficientData as exc:
                figures.append(PositioningFigures(velocity, load, band, numbers, tuple(complete), None, str(exc)))
    return PositioningRun(
        run_id, design, tuple(run.config.get("skipped_steps") or ()), bands, hysteresis, source, tuple(figures), series
    )


@dataclass(frozen=True, kw_only=True)
class PositioningTimeReport(ReportBase):
    """Everything the report of an iso9283_positioning_time run prints."""

    analysis: PositioningRun
    store_path: str


def positioning_time_deviations(run, analysis: PositioningRun) -> list[Deviation]:
    """Departures of a positioning-time run from ISO 9283 clause 9 (iso9283.md §6.15): cycles, the Table 19 steps
    (skipped or changed ones), velocity, load, the band and the hysteresis chosen at analysis."""
    config, robot = run.config, run.settings.get("robot") or {}
    measured = min(len(f.cycles) for f in analysis.figures)
    rows = [
        _planned_count(
            "ISO 9283 6.9",
            "cycles",
            f"{CYCLES} cycles (Table 5)",
            config,
            "cycles",
            measured=measured,
            required=CYCLES,
            counted="complete",
            where="any condition",
            effect="mean positioning times over fewer cycles than the standard's",
        )
    ]
    table19 = [float(v) for v in config.get("steps_mm", ())]
    driven = ", ".join(f"{int(s['step'])}: {float(s['distance_mm']):+g}" for s in analysis.steps)
    skipped = "; ".join(
        f"step {int(s['step'])} to ({_fmt(s['target_mm'])}) mm: outside the workspace" for s in analysis.skipped
    )
    rows.append(
        _row(
            "ISO 9283 9",
            "steps",
            "the 7 steps of Table 19 from P1 (-10, +20, -50, +100, -200, +500, "
            "-1000 mm), Dx = Dy = Dz, read as per-axis increments [U]",
            f"steps driven (number: per-axis mm) {driven}" + (f"; skipped {skipped}" if skipped else ""),
            len(analysis.steps) == TABLE_19_STEPS and table19 == [-10.0, 20.0, -50.0, 100.0, -200.0, 500.0, -1000.0],
            "positioning times only for the steps driven; the long steps do not fit the workspace",
        )
    )
    velocities = [float(v) for v in config.get("velocities_pct", ())]
    rows.append(
        _row(
            "ISO 9283 9",
            "velocity",
            "100 % of rated velocity and velocities optimised per step, the velocities used stated [N]",
            f"{_fmt(velocities)} % of the rated step rate ({robot.get('rated_speed_steps_s', '—')} "
            "steps/s), the same for every step",
            False,
            "no per-step optimised velocity: the figures are those of the stated velocities",
        )
    )
    load = _load(config, robot)
    rows.append(replace(load, clause="ISO 9283 6.6", effect=load.effect and "the times hold for the stated loads only"))
    rows.append(
        _row(
            "ISO 9283 9",
            "limit band",
            f"the limit band of 7.4; comparison bands {_fmt(ISO_BANDS_MM)} mm [N]",
            f"{_fmt(analysis.bands_mm)} mm, chosen at analysis",
            all(b in ISO_BANDS_MM for b in analysis.bands_mm),
            "not comparable with comparison-test results",
        )
    )
    rows.append(
        _row(
            "ISO 9283 9",
            "hysteresis",
            "stabilised: inside the band from then on (as written) [U]",
            "h = 0, the definition as written"
            if analysis.hysteresis_mm == 0
            else f"h = {analysis.hysteresis_mm:g} mm ({analysis.hysteresis_source})",
            analysis.hysteresis_mm == 0,
            "excursions up to h beyond the band are not counted",
        )
    )
    return rows


def collect_positioning_time(
    store: Store,
    run_id: int,
    *,
    k: float = 2.0,
    resamples: int = 1000,
    allow_unknown: bool = False,
    bands_mm=None,
    hysteresis_mm: float | None = None,
) -> PositioningTimeReport:
    """Gather the facts and figures of the report of positioning-time run ``run_id`` (``k``, ``resamples`` and
    ``allow_unknown`` unused: the times carry no expanded uncertainty and no row here can be unknown)."""
    run = store.run(run_id)
    analysis = analyze_positioning_run(store, run_id, bands_mm=bands_mm, hysteresis_mm=hysteresis_mm)
    calibrations = calibrations_in_force(store, run)
    base = provenance(run, calibrations)
    notes = tuple(
        f"{f.velocity_pct:g} %, {f.load_kg:g} kg, {f.band_mm:g} mm band: no figure ({f.reason})"
        for f in analysis.figures
        if f.result is None
    )
    return PositioningTimeReport(
        **{**base, "notes": base["notes"] + notes},
        title=run.config.get("title") or "ISO 9283-style minimum positioning time",
        clauses=("9 minimum positioning time",),
        deviations=tuple(positioning_time_deviations(run, analysis)),
        instrument=counts_instrument(run, calibrations, 0),
        table=run_table(store, run_id, "positioning", series=True),
        coverage_factor=k,
        analysis=analysis,
        store_path=store.path,
    )


def _results(report: PositioningTimeReport) -> tuple:
    a = report.analysis
    rows, cycles = [], []
    for f in a.figures:
        condition = (f"{f.velocity_pct:g}", f"{f.load_kg:g}", f"{f.band_mm:g}")
        if f.result is None:
            rows.append((*condition, "—", "—", "—", "—", f"no figure: {f.reason}"))
            continue
        r = f.result
        for i, step in enumerate(f.steps):
            rows.append(
                (
                    *condition,
                    str(step),
                    f"{r.step_distance_mm[i]:.2f}",
                    f"{r.mean_time_s[i]:.3f}",
                    f"{r.max_time_s[i]:.3f}",
                    "",
                )
            )
            cycles += [(*condition, str(step), str(c), f"{t:.3f}") for c, t in zip(f.cycles, r.time_s_per_cycle[i])]
    h = f"h = {a.hysteresis_mm:g} mm"
    return (
        Table(
            "positioning-time",
            (
                "v (%)",
                "Load (kg)",
                "Band B (mm)",
                "Step",
                "Attained |Δp| (mm)",
                "mean t_pos (s)",
                "max t_pos (s)",
                "Note",
            ),
            tuple(rows),
            f"Minimum positioning time (ISO 9283 9) per step of Table 19: mean and largest over the cycles ({h}, "
            f"{a.hysteresis_source})",
        ),
        Table(
            "positioning-cycles",
            ("v (%)", "Load (kg)", "Band B (mm)", "Step", "Cycle", "t_pos (s)"),
            tuple(cycles),
            "Every step and cycle: from leaving the start band to stabilised in the band",
        ),
    )


def positioning_time_plot(report: PositioningTimeReport) -> Plot:
    """Per step (highest velocity, first load): the distance from the settled position |p(t) − p_end| of every cycle
    against the time from leaving the start pose, on one scale, with the limit bands; one legend."""
    a = report.analysis
    key = next(iter(a.series))
    steps = a.series[key]
    grid = print_grid(len(steps), (3.0, 2.2), max_columns=3, y_log=True)
    smallest = min(a.bands_mm)
    for panel, (step, cycles) in zip(grid.panels, steps.items()):
        for index, (cycle, t, p) in enumerate(cycles):
            moved = np.flatnonzero(np.linalg.norm(p - p[0], axis=1) > smallest)
            t0 = t[moved[0]] if len(moved) else t[0]
            panel.plot(
                t - t0, np.linalg.norm(p - p[-1], axis=1), lw=0.8, color=f"C{index % 10}", label=f"cycle {cycle}"
            )
        for band in a.bands_mm:
            panel.hline(band, ls="--", color="tab:red", lw=0.7, label="limit bands B")
        panel.vline(0.0, color="0.5", lw=0.7)
        panel.set_title(f"step {step}")
    figure = grid.finish(
        f"t from leaving the {smallest:g} mm band of the start pose (s)",
        "|p(t) − p_end| (mm)",
        legend_pt=MIN_FONT_PT,
        legend_columns=4,
    )
    return Plot(
        f"Each step at {key[0]:g} % ({key[1]:g} kg): distance from the settled position per cycle against the "
        f"time from leaving the start pose, with the limit bands {_fmt(a.bands_mm)} mm (dashed); the "
        "positioning time ends where a curve enters its band for good.",
        figure,
    )


def recompute_positioning_time(report: PositioningTimeReport) -> str:
    """The command that gives every figure again from the store."""
    a = report.analysis
    return (
        f"bench analyze positioning-run {report.run.id} --store {report.store_path} --band-mm "
        f"{' '.join(f'{b:g}' for b in a.bands_mm)} --hysteresis-mm {a.hysteresis_mm!r} --json (one condition: "
        "bench analyze positioning-time on the raw-data file below with the same options)"
    )


def positioning_time_document(
    report: PositioningTimeReport,
    raw: list[RawData],
    *,
    operator: str = "—",
    laboratory: str = "—",
):
    config = report.run.config
    method = (
        "ISO 9283:1998 clause 9. From rest at P1 the robot steps through the Table 19 sequence (each distance "
        "a per-axis increment, Dx = Dy = Dz); every target passed the pre-flight (reachable, within the joint "
        "limits, away from singularities) and a target outside the workspace was skipped. Each step's "
        f"position is streamed from {config.get('rest_s', '—')} s before its move starts to "
        f"{config.get('hold_s', '—')} s after the move is reported done. t_leave = the first time |p(t) − "
        "p(t_0)| > B; t_2 = the first time from which p stays within B + h of its settled (last) position; "
        "t_pos = t_2 − t_leave; per step the mean and the largest over the cycles."
    )
    stated = (
        ("Cycles of the step sequence", "cycles"),
        ("Start pose P1 (mm)", "p1_mm"),
        ("Dwell at P1 before each cycle (s)", "settle_s"),
        ("Step distances, Dx = Dy = Dz (mm)", "steps_mm"),
        ("Rest streamed before each move (s)", "rest_s"),
        ("Streamed after each move (s)", "hold_s"),
    )
    extra = tuple(
        (name, _fmt(config[key]) if isinstance(config[key], list) else f"{config[key]:g}")
        for name, key in stated
        if key in config
    ) + (
        ("Limit bands (mm, chosen at analysis)", _fmt(report.analysis.bands_mm)),
        ("Hysteresis h (mm)", f"{report.analysis.hysteresis_mm:g} ({report.analysis.hysteresis_source})"),
        ("Time base", str(report.run.settings.get("time_base", "not stated"))),
    )
    return assemble(
        report,
        raw,
        operator=operator,
        laboratory=laboratory,
        method=method,
        scope=SCOPE,
        conditions=conditions_section(report, ("velocities_pct", "loads_kg"), extra),
        results=(
            *_results(report),
            Paragraph(
                "The times carry no expanded uncertainty here; the instrument's report interval and one "
                "count set the smallest difference they can show."
            ),
        ),
        plots=[positioning_time_plot(report)],
        decision=decision_section(report, NO_CRITERION),
        recompute=recompute_positioning_time(report),
    )


#: What ``--criterion`` judges in a positioning-time report: the ISO figure (the mean over the cycles) of every
#: Table 19 step, condition and band (no U stated).
CHARACTERISTICS = {
    "t_pos_s": Characteristic(
        "minimum positioning time (mean over the cycles) of every step, condition and band",
        lambda report: [
            (f"step {step}, {f.band_mm:g} mm band, {f.velocity_pct:g} % velocity, {f.load_kg:g} kg", mean, None)
            for f in report.analysis.figures
            if f.result is not None
            for step, mean in zip(f.steps, f.result.mean_time_s)
        ],
    ),
}
