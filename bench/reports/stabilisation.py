"""The report of an ``iso9283_stabilisation`` run: position stabilisation time and overshoot (ISO 9283 7.4, 7.5)
from the streamed arrivals (docs/campaigns.md, "Streamed arrivals").

Every figure comes from :func:`bench.metrology.stabilisation_tables.stabilisation_results` on the run's streamed series
(:func:`bench.store.series_table`, the raw-data CSV, = ``bench export RUN --series``), the call ``bench analyze
stabilisation FILE.csv --band-mm ... --hysteresis-mm ...`` makes: per pose and cycle through
:func:`bench.metrology.pose_stabilisation`, for every limit band (ISO comparison bands 0.1, 0.5 and 1.0 mm by
default). Runs at several velocities or loads are analysed per condition.

Hysteresis h (band-edge flicker of a quantised instrument): by default one count of a counts instrument (the
mice), from the run's stored calibration in force (``mm_per_count``, or ``cpi``) or else its stored instrument
settings (25.4/cpi mm), rounded to 6 significant digits so that the printed command reproduces the figures
exactly; 0 (the definition as written) when the run stores neither. The caller may set it. The report states
which and why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.errors import ConfigError
from bench.metrology import PoseStabilisation
from bench.metrology.stabilisation_tables import stabilisation_results, stabilisation_table
from bench.reports.content import ReportBase, calibrations_in_force, provenance, run_table
from bench.reports.criteria import Characteristic, decision_section
from bench.reports.deviations_arrivals import ISO_BANDS_MM, stabilisation_deviations
from bench.reports.document import (
    Block,
    Document,
    Paragraph,
    RawData,
    Table,
    assemble,
    conditions_section,
    reading_formatter,
)
from bench.reports.instrument import MM_PER_INCH, counts_instrument
from bench.reports.plots import MIN_FONT_PT, Plot, print_grid
from bench.store import CalibrationRecord, RunRecord, Store

__all__ = [
    "Arrival",
    "BandResult",
    "StabilisationReport",
    "collect_stabilisation",
    "count_size_mm",
    "recompute_stabilisation",
    "stabilisation_document",
    "stabilisation_plot",
]

SCOPE = (
    "Tested following the methods of ISO 9283:1998 clauses 7.4 (position stabilisation time) and 7.5 (position "
    "overshoot), with the deviations listed in the deviations table. Results are ISO 9283-style; this is not "
    "an ISO 9283 certification."
)
NO_CRITERION = "no acceptance criterion stated: no pass/fail statement (ISO 9283 defines methods, not grades)"


@dataclass(frozen=True)
class Arrival:
    """One cycle's streamed arrival at one pose, as d(t) = |p(t) − p_att| with p_att its last sample (the
    settled attained position :func:`bench.metrology.position_stabilisation` measures against)."""

    group: str  #: pose label, with the condition when the run varies one
    cycle: int
    t_s: np.ndarray  #: relative to the move-done signal
    distance_mm: np.ndarray


@dataclass(frozen=True)
class BandResult:
    """Stabilisation at one pose (and condition) in one limit band, or why there is none."""

    group: str
    band_mm: float
    cycles: tuple[int, ...]  #: the cycle numbers analysed, in order (result.cycles follows it)
    result: PoseStabilisation | None
    reason: str = ""  #: why result is None (an arrival never entered, or never settled in, the band)


@dataclass(frozen=True, kw_only=True)
class StabilisationReport(ReportBase):
    """Everything the report of an iso9283_stabilisation run prints."""

    bands_mm: tuple[float, ...]
    hysteresis_mm: float
    hysteresis_source: str
    count_mm: float | None  #: one count of the instrument, None when the run stores none
    results: tuple[BandResult, ...]  #: per group, then band
    arrivals: tuple[Arrival, ...]
    store_path: str  #: for the exact bench export command


def count_size_mm(run: RunRecord, calibrations: tuple[CalibrationRecord, ...]) -> tuple[float, str] | None:
    """One count of the run's counts instrument (mm) and where it comes from: a calibration in force
    (``mm_per_count``, else ``cpi``), else ``settings.instrument.cpi``; None for an instrument without counts."""
    for record in calibrations:
        where = f"calibration {record.name} v{record.version} (id {record.id})"
        if "mm_per_count" in record.params:
            return float(record.params["mm_per_count"]), f"{where}: mm_per_count"
        if "cpi" in record.params:
            cpi = float(record.params["cpi"])
            return MM_PER_INCH / cpi, f"{where}: {cpi:g} counts per inch"
    cpi = (run.settings.get("instrument") or {}).get("cpi")
    if cpi is None:
        return None
    return MM_PER_INCH / float(cpi), f"the instrument's stated {float(cpi):g} counts per inch"


def _hysteresis(count: tuple[float, str] | None, requested: float | None) -> tuple[float, str]:
    if requested is not None:
        if not requested >= 0:
            raise ConfigError(f"--hysteresis-mm {requested:g}: expected a number >= 0 (mm)")
        return float(requested), "set for this report (--hysteresis-mm)"
    if count is None:
        return 0.0, "the run states no instrument count (counts per inch, or a calibration's mm per count)"
    return float(f"{count[0]:.6g}"), f"one instrument count, {count[1]}"


def _bands(requested) -> tuple[float, ...]:
    bands = tuple(float(b) for b in (requested if requested is not None else ISO_BANDS_MM))
    if not bands or not all(b > 0 for b in bands):
        raise ConfigError(f"--band-mm {' '.join(f'{b:g}' for b in bands) or '(none)'}: expected limit bands > 0 mm")
    return bands


def _window_problems(arrivals: list[Arrival], results: list[BandResult], bands: tuple[float, ...]) -> tuple[str, ...]:
    """Per band, the arrivals whose window opened already inside it (t_1 not observed: the lead window missed the
    entry), then the bands in which some arrival never entered or never settled."""
    problems = []
    for band in bands:
        inside = [a for a in arrivals if a.distance_mm[0] <= band]
        if inside:
            problems.append(
                f"{band:g} mm band: {len(inside)} of {len(arrivals)} arrivals began inside it (t_1 is "
                "the window's start)"
            )
    problems += [f"{r.group}, {r.band_mm:g} mm: {r.reason}" for r in results if r.result is None]
    return tuple(problems)


def collect_stabilisation(
    store: Store,
    run_id: int,
    *,
    k: float = 2.0,
    resamples: int = 1000,
    allow_unknown: bool = False,
    bands_mm=None,
    hysteresis_mm: float | None = None,
) -> StabilisationReport:
    """Gather the facts and figures of the report of ``iso9283_stabilisation`` run ``run_id``.

    ``bands_mm`` defaults to the ISO comparison bands; ``hysteresis_mm`` to one count of the run's instrument (see
    the module docstring). ``k`` and ``resamples`` are unused (these figures carry no expanded uncertainty)."""
    run = store.run(run_id)
    bands = _bands(bands_mm)
    table = run_table(store, run_id, "arrival", series=True)
    calibrations = calibrations_in_force(store, run)
    count = count_size_mm(run, calibrations)
    hysteresis, source = _hysteresis(count, hysteresis_mm)
    figures = stabilisation_results(stabilisation_table(table), bands, hysteresis)
    results, arrivals = [], []
    for label, series in figures.series.items():
        arrivals += [
            Arrival(label, cycle, t, np.sqrt(np.sum((position - position[-1]) ** 2, axis=1)))
            for cycle, t, position in series
        ]
        numbers = tuple(cycle for cycle, _, _ in series)
        for band in bands:
            result = figures.bands[band][label]
            results.append(
                BandResult(label, band, numbers, None, result)
                if isinstance(result, str)
                else BandResult(label, band, numbers, result)
            )
    cycles = min(len(r.cycles) for r in results)
    problems = _window_problems(arrivals, results, bands)
    deviations = stabilisation_deviations(
        config=run.config,
        settings=run.settings,
        cycles_measured=cycles,
        bands_mm=bands,
        hysteresis_mm=hysteresis,
        hysteresis_source=source,
        count_mm=None if count is None else count[0],
        window_problems=problems,
        allow_unknown=allow_unknown,
    )
    base = provenance(run, calibrations)
    return StabilisationReport(
        **{
            **base,
            "notes": base["notes"]
            + tuple(f"{r.group}, {r.band_mm:g} mm band: no figure ({r.reason})" for r in results if r.result is None),
        },
        title=run.config.get("title") or "ISO 9283-style position stabilisation time and overshoot",
        clauses=("7.4 position stabilisation time", "7.5 position overshoot"),
        deviations=tuple(deviations),
        instrument=counts_instrument(run, calibrations, 0),
        table=table,
        coverage_factor=k,
        bands_mm=bands,
        hysteresis_mm=hysteresis,
        hysteresis_source=source,
        count_mm=None if count is None else count[0],
        results=tuple(results),
        arrivals=tuple(arrivals),
        store_path=store.path,
    )


def _seconds(value: float) -> str:
    return f"{value:.3f}"


def _results(report: StabilisationReport) -> tuple[Block, ...]:
    h = f"h = {report.hysteresis_mm:g} mm"
    mm = reading_formatter(report)
    summary, cycles = [], []
    for r in report.results:
        if r.result is None:
            summary.append(
                (r.group, f"{r.band_mm:g}", str(len(r.cycles)), "—", "—", "—", "—", f"no figure: {r.reason}")
            )
            continue
        s = r.result
        summary.append(
            (
                r.group,
                f"{r.band_mm:g}",
                str(len(r.cycles)),
                _seconds(s.mean_time_s),
                _seconds(s.max_time_s),
                mm(s.mean_overshoot_mm),
                mm(s.max_overshoot_mm),
                "",
            )
        )
        cycles += [
            (
                r.group,
                f"{r.band_mm:g}",
                str(cycle),
                _seconds(c.first_entry_s),
                _seconds(c.settled_s),
                _seconds(c.stabilisation_time_s),
                mm(c.overshoot_mm),
            )
            for cycle, c in zip(r.cycles, s.cycles)
        ]
    return (
        Table(
            "stabilisation",
            ("Pose", "Band B (mm)", "Cycles", "mean t_s (s)", "max t_s (s)", "OV (mm)", "max OV (mm)", "Note"),
            tuple(summary),
            f"Position stabilisation time t_s (ISO 9283 7.4) and overshoot OV (7.5) per pose and limit band: mean "
            f"and largest over the cycles ({h}, {report.hysteresis_source})",
        ),
        Table(
            "stabilisation-cycles",
            ("Pose", "Band B (mm)", "Cycle", "t_1 (s)", "t_2 (s)", "t_s (s)", "OV_j (mm)"),
            tuple(cycles),
            "Every arrival: first entry into the band t_1, settled from t_2 on, t_s = t_2 − t_1 and "
            "its overshoot (times relative to the move-done signal)",
        ),
        Paragraph(
            f"Hysteresis used: {h} ({report.hysteresis_source}). "
            + (
                "Excursions up to B + h after the first entry are not counted as leaving the band or as overshoot."
                if report.hysteresis_mm
                else "The definitions as written: any excursion beyond B counts."
            )
        ),
    )


def stabilisation_plot(report: StabilisationReport) -> Plot:
    """Per pose (and condition), on one scale: d(t) of every cycle with the limit bands (and B + h), t = 0 the
    move-done signal; in the smallest band, every cycle's first entry t_1, settled time t_2 (t_s = t_2 − t_1)
    and, where it exceeds B + h, the overshoot OV at the peak it is read from. One legend for the figure."""
    groups = list(dict.fromkeys(a.group for a in report.arrivals))
    grid = print_grid(len(groups), (3.0, 2.2), max_columns=3)
    top = 2.0 * max(report.bands_mm)
    marked = min(report.bands_mm)
    by_key = {(r.group, r.band_mm): r for r in report.results}
    colours = [f"C{i}" for i in range(10)]
    for panel, group in zip(grid.panels, groups):
        mark = by_key.get((group, marked))
        figures = dict(zip(mark.cycles, mark.result.cycles)) if mark is not None and mark.result else {}
        for index, arrival in enumerate(a for a in report.arrivals if a.group == group):
            colour = colours[index % len(colours)]
            panel.plot(arrival.t_s, arrival.distance_mm, lw=0.8, color=colour, label=f"cycle {arrival.cycle}")
            cycle = figures.get(arrival.cycle)
            if cycle is None:
                continue
            panel.plot(
                cycle.first_entry_s,
                marked,
                marker="o",
                ms=4,
                mfc="none",
                color="black",
                ls="",
                label=f"t_1: first entry into B = {marked:g} mm",
            )
            panel.plot(
                cycle.settled_s,
                marked,
                marker="s",
                ms=4,
                mfc="none",
                color="tab:green",
                ls="",
                label="t_2: inside from here on (t_s = t_2 − t_1)",
            )
            panel.plot([cycle.first_entry_s, cycle.settled_s], [marked, marked], color="tab:green", lw=2.0, alpha=0.6)
            if cycle.overshoot_mm > 0:
                panel.plot(
                    cycle.peak_s,
                    min(cycle.overshoot_mm, top),
                    marker="v",
                    ms=5,
                    color="tab:red",
                    ls="",
                    label="OV: largest d(t) after t_1",
                )
        for band in report.bands_mm:
            panel.hline(band, ls="--", color="tab:red", lw=0.7)
            if report.hysteresis_mm:
                panel.hline(band + report.hysteresis_mm, ls=":", color="tab:red", lw=0.6)
        panel.vline(0.0, color="0.5", lw=0.7)
        panel.set_title(group)
    grid.ylim = (0.0, top)
    figure = grid.finish(
        "t from the move-done signal (s)",
        "d(t) = |p(t) − p_att| (mm)",
        legend_pt=MIN_FONT_PT,
        legend_columns=4,
        legend_order=lambda label: not label.startswith("cycle"),
    )  # curves first
    bands = ", ".join(f"{b:g}" for b in report.bands_mm)
    return Plot(
        f"Arrival at each pose, every panel on one scale: distance d(t) from the settled position (the last "
        f"sample) per cycle, with the limit bands {bands} mm (dashed)"
        + (f" and B + h, h = {report.hysteresis_mm:g} mm (dotted)" if report.hysteresis_mm else "")
        + f"; in the {marked:g} mm band the first entry t_1, the settled time t_2 (green bar: t_s) and the "
        f"overshoot OV where it is read; clipped at {top:g} mm (the approach lies above).",
        figure,
    )


def recompute_stabilisation(report: StabilisationReport) -> str:
    """The exact commands that give every figure again from the store."""
    run_id = report.run.id
    bands = " ".join(f"{b:g}" for b in report.bands_mm)
    return (
        f"bench export {run_id} --series --store {report.store_path} --out run{run_id}_series.csv, then bench "
        f"analyze stabilisation run{run_id}_series.csv --band-mm {bands} --hysteresis-mm "
        f"{report.hysteresis_mm!r} --json (or on the raw-data file below, the same rows at full precision)"
    )


def stabilisation_document(
    report: StabilisationReport, raw: list[RawData], *, operator: str = "—", laboratory: str = "—"
) -> Document:
    config = report.run.config
    method = (
        f"ISO 9283:1998 7.4 and 7.5. Each visit moves to the pose and, with no dwell, captures the streamed "
        f"arrival from {config.get('lead_s', '—')} s before the controller reports the move done to "
        f"{config.get('hold_s', '—')} s after. Per arrival: d(t) = |p(t) − p_att| with p_att its last "
        "sample; t_1 = first time d <= B; t_2 = first time from which d <= B + h for the rest of the arrival; "
        "t_s = t_2 − t_1; OV_j = max d after t_1 when it exceeds B + h, else 0 (h: hysteresis, 0 in the "
        "standard). Per pose and band: mean and largest t_s and OV_j over the cycles "
        "(bench.metrology.pose_stabilisation)."
    )
    settings = report.run.settings
    extra = (
        ("time base", str(settings.get("time_base", "not stated"))),
        ("limit bands (mm, chosen at analysis)", ", ".join(f"{b:g}" for b in report.bands_mm)),
        ("hysteresis h (mm)", f"{report.hysteresis_mm:g} ({report.hysteresis_source})"),
    )
    return assemble(
        report,
        raw,
        operator=operator,
        laboratory=laboratory,
        method=method,
        scope=SCOPE,
        conditions=conditions_section(
            report,
            (
                "velocities_pct",
                "loads_kg",
                "cycles",
                "lead_s",
                "hold_s",
                "cube_centre_mm",
                "cube_side_mm",
                "poses",
                "warmup_s",
                "ambient_c",
            ),
            extra,
        ),
        results=_results(report),
        plots=[stabilisation_plot(report)],
        decision=decision_section(report, NO_CRITERION),
        recompute=recompute_stabilisation(report),
    )


def _figures(report, figure: str):
    return [
        (f"{r.group}, {r.band_mm:g} mm band", getattr(r.result, figure), None)
        for r in report.results
        if r.result is not None
    ]


#: What ``--criterion`` judges in a stabilisation report: per pose and band, the largest stabilisation time and
#: overshoot over the cycles (no U stated).
CHARACTERISTICS = {
    "t_s": Characteristic("largest stabilisation time of every pose and band", lambda r: _figures(r, "max_time_s")),
    "OV_mm": Characteristic("largest overshoot of every pose and band", lambda r: _figures(r, "max_overshoot_mm")),
}
