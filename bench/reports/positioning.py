"""The report of a ``delta_positioning`` run: the delta thesis's positioning test (§8.4.2) read by the laser grid,
whose readings are partial (docs/campaigns.md, "Delta robot positioning read by the laser grid"); and of any pose
protocol (``iso9283_pose``, a kinematic validation) whose samples are laser-grid readings (:func:`grid_readings`),
with the thesis's rows left out: the same partial-pose statistics, never a filled axis.

Every figure comes from :mod:`bench.metrology.partial_pose` on the run's tidy ``pose`` table (the raw-data CSV),
the same calls ``bench analyze grid-positioning FILE.csv`` makes: ``grid_positioning_table`` (checks that every
stored axis comes from a valid screen), ``analyze_grid_positioning`` (per pose: each screen's valid and lit rates
with their Wilson interval at z = k, ``--k`` of both, 2 by default; per-axis n, AP, 3 S, max |e|, mean |e| over the
readings that measured the axis; spatial AP and RP over the complete readings) and ``pooled_axis_errors`` (the
thesis's summary over every pose), the rates printed by ``rate_text``. A missing axis is never filled: an axis
without a reading prints "no reading", a statistic with too few readings "—".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.metrology.documents import GRID_RESOLUTION_MM
from bench.metrology.formatting import format_length
from bench.metrology.partial_pose import (
    AXIS_NAMES,
    NO_READING,
    AxisErrors,
    GridPoseResult,
    analyze_grid_positioning,
    grid_positioning_table,
    pooled_axis_errors,
    rate_text,
)
from bench.reports.content import ReportBase, calibrations_in_force, provenance, run_table
from bench.reports.criteria import Characteristic, decision_section
from bench.reports.deviations_arrivals import grid_positioning_deviations
from bench.reports.document import (
    Block,
    Document,
    Paragraph,
    RawData,
    Table,
    assemble,
    conditions_section,
)
from bench.reports.instrument import InstrumentInfo
from bench.reports.plots import Plot, panels
from bench.store import Store

__all__ = [
    "NO_READING",
    "GridPositioningReport",
    "axis_cells",
    "collect_grid_positioning",
    "grid_positioning_document",
    "grid_positioning_plot",
    "grid_readings",
    "recompute_grid_positioning",
]

SCREENS = ("horizontal", "vertical")
SCOPE = (
    "Tested following the positioning test of the delta thesis (§8.4.2) with the laser grid as the instrument, "
    "and reporting ISO 9283-style AP and RP over the complete readings, with the deviations listed in the "
    "deviations table. Every figure is conditional on the grid detecting the pose. This is not an ISO 9283 "
    "certification."
)
ISO_SCOPE = (
    "Tested following ISO 9283 (7.2.1 AP, 7.2.2 RP) with the laser grid as the instrument, whose readings "
    "are partial: per-axis figures over the readings that measured each axis, AP_P and RP_l over the "
    "complete readings only, with the deviations listed in the deviations table. Every figure is "
    "conditional on the grid detecting the pose. This is not an ISO 9283 certification."
)
NO_CRITERION = "no acceptance criterion stated: no pass/fail statement (the thesis and ISO 9283 set none)"
CONDITIONAL = (
    "Reading the figures: they are conditional on detection. The grid measures an axis only when a laser "
    f"spot falls within the detection window r of a sensor (a {GRID_RESOLUTION_MM:g} mm lattice; with "
    "r = 1 mm about half of all positions are blind), so the readings of a pose are not a random sample "
    "of its scatter, and each carries ±r. Which poses the grid sees at all depends on where the screens "
    "are placed: with the default placement (the legacy GUI drawing) the thesis's poses sit between four "
    "sensors of both screens, so the placement must come from the software calibration "
    "(delta4-lasergrid.md §6.5) before the rates mean anything on the rig (docs/campaigns.md, "
    "docs/sensors.md)."
)


@dataclass(frozen=True, kw_only=True)
class GridPositioningReport(ReportBase):
    """Everything the report of a delta_positioning run prints."""

    poses: tuple[GridPoseResult, ...]
    pooled: tuple[AxisErrors, ...]  #: x, y, z over every pose (the thesis's summary)
    store_path: str  #: for the exact bench export command


def _grid_instrument(run, calibrations) -> InstrumentInfo:
    """The laser grid: a reading lies within ±r of the true position (rectangular, u = r/√3 per axis)."""
    settings = dict(run.settings.get("instrument") or {})
    window = (settings.get("decoder") or {}).get("spot_half_width_mm")
    budget = (
        ()
        if window is None
        else (
            (
                "detection window ±r (a reading is the lattice point within r of the true position)",
                float(window) / math.sqrt(3.0),
                f"settings.instrument.decoder.spot_half_width_mm = {window:g} mm, rectangular",
            ),
        )
    )
    return InstrumentInfo(settings, budget[0][1] if budget else None, budget, 0, None, calibrations)


def _notes(poses: tuple[GridPoseResult, ...]) -> tuple[str, ...]:
    notes = []
    for p in poses:
        unread = [name for name, axis in zip(AXIS_NAMES, p.statistics.axes) if axis.n == 0]
        if unread:
            notes.append(
                f"{p.pose}: {', '.join(unread)} {'was' if len(unread) == 1 else 'were'} never measured in "
                f"{p.statistics.n_readings} readings (no screen decoded it): reported as {NO_READING}"
            )
    return tuple(notes)


def _thesis(run) -> bool:
    """Whether the run is the thesis's positioning test (else an ISO pose protocol read by the laser grid)."""
    return run.protocol_name == "delta_positioning"


def grid_readings(store: Store, run_id: int) -> bool:
    """Whether the run's pose samples are laser-grid readings (they carry the screens' valid flags)."""
    return any("horizontal_valid" in sample.values for sample in store.samples(run_id, kind="pose"))


def collect_grid_positioning(
    store: Store, run_id: int, *, k: float = 2.0, resamples: int = 1000, allow_unknown: bool = False
) -> GridPositioningReport:
    """Gather the facts and figures of the report of ``delta_positioning`` run ``run_id`` (``resamples`` unused;
    ``k`` is the z of the rates' Wilson intervals, as ``bench analyze grid-positioning --k``)."""
    run = store.run(run_id)
    table = run_table(store, run_id, "pose")
    analysed = grid_positioning_table(table)  # NaN: an axis not measured, as an empty CSV cell
    poses = tuple(analyze_grid_positioning(analysed, k=k))
    calibrations = calibrations_in_force(store, run)
    deviations = grid_positioning_deviations(
        config=run.config, settings=run.settings, poses=poses, allow_unknown=allow_unknown, thesis=_thesis(run)
    )
    base = provenance(run, calibrations)
    thesis = _thesis(run)
    return GridPositioningReport(
        **{**base, "notes": base["notes"] + _notes(poses)},
        title=run.config.get("title")
        or (
            "Delta robot positioning read by the laser grid (thesis §8.4.2)"
            if thesis
            else f"ISO 9283-style pose accuracy and repeatability ({run.protocol_name})"
            " read by the laser grid (partial readings)"
        ),
        reference="thesis §8.4.2 / ISO 9283" if thesis else "ISO 9283",
        clauses=(
            ("delta thesis §8.4.2: per-axis error, max |e| and mean |e| at three poses",)
            if thesis
            else ("ISO 9283 7.2.1 AP per axis, over the readings that measured the axis",)
        )
        + ("ISO 9283 7.2.1 AP and 7.2.2 RP, over the complete readings only",),
        deviations=tuple(deviations),
        instrument=_grid_instrument(run, calibrations),
        table=table,
        coverage_factor=k,
        poses=poses,
        pooled=pooled_axis_errors(analysed),
        store_path=store.path,
    )


def _value(value: float | None, *, signed: bool = False, missing: str = "—") -> str:
    if value is None:
        return missing
    # the grid reads whole lattice steps: no figure gets more decimals than its readings carry
    return format_length(value, resolution=GRID_RESOLUTION_MM, signed=signed)


def axis_cells(axis: AxisErrors) -> tuple[str, ...]:
    """n, AP, 3 S, max |e|, mean |e| of one axis: "no reading" for n = 0, "—" where there are too few readings."""
    if axis.n == 0:
        return (NO_READING, "—", "—", "—", "—")
    return (
        str(axis.n),
        _value(axis.ap_mm, signed=True),
        _value(axis.spread_3s_mm, missing="— (n = 1)"),
        _value(axis.max_abs_error_mm),
        _value(axis.mean_abs_error_mm),
    )


def _results(report: GridPositioningReport) -> tuple[Block, ...]:
    z = f"{report.coverage_factor:g}"
    screens = tuple(
        (
            p.pose,
            ", ".join(f"{v:g}" for v in p.commanded_mm),
            str(p.statistics.n_readings),
            *(rate_text(getattr(p, kind)[screen]) for screen in SCREENS for kind in ("valid", "lit")),
        )
        for p in report.poses
    )
    axes = tuple(
        (p.pose, name, f"{command:g}", *axis_cells(axis))
        for p in report.poses
        for name, command, axis in zip(AXIS_NAMES, p.commanded_mm, p.statistics.axes)
    )
    spatial = tuple(
        (
            p.pose,
            f"{p.statistics.n_complete} / {p.statistics.n_readings}",
            _value(p.statistics.ap_mm, missing="— (no complete reading)"),
            _value(p.statistics.rp_mm, missing="— (fewer than 2 complete readings)"),
        )
        for p in report.poses
    )
    pooled = tuple((name, *axis_cells(axis)) for name, axis in zip(AXIS_NAMES, report.pooled))
    axis_header = ("n", "AP = x̄ − x_c (mm)", "3 S (mm)", "max |e| (mm)", "mean |e| (mm)")
    return (
        Table(
            "grid-screens",
            (
                "Pose",
                "Command x, y, z (mm)",
                "Readings",
                "Horizontal valid",
                "Horizontal lit",
                "Vertical valid",
                "Vertical lit",
            ),
            screens,
            f"Per pose and screen: valid = the screen decoded (its axes stored), lit = some sensor reported; k / n, "
            f"rate [Wilson score interval, z = {z}]",
        ),
        Table(
            "grid-axes",
            ("Pose", "Axis", "Command (mm)", *axis_header),
            axes,
            f"Per pose and axis, over the readings that measured the axis (n; {NO_READING}: no screen measured "
            "it); AP signed, 3 S the per-axis spread (not an ISO RP), max |e| and mean |e| the thesis's figures",
        ),
        Table(
            "grid-spatial",
            ("Pose", "Complete readings", "AP_P (mm)", "RP_l (mm)"),
            spatial,
            "ISO 9283 7.2.1/7.2.2 AP_P and RP_l over the complete readings only (all three axes in one reading)",
        ),
        Table(
            "grid-pooled",
            ("Axis", *axis_header),
            pooled,
            "Every pose together (the thesis's summary, §8.4.2): the errors x_j − x_c of all stored readings",
        ),
        Paragraph(CONDITIONAL),
    )


def grid_positioning_plot(report: GridPositioningReport) -> Plot:
    """Left: each screen's valid rate per pose with its Wilson interval (lit rate beside it). Right: every stored
    reading minus its command, per pose and axis; an axis without a reading is marked."""
    figure, (rates, errors) = panels(2, max_columns=2, size=(5.0, 3.4))
    position = np.arange(len(report.poses))
    for offset, screen, colour in ((-0.15, "horizontal", "tab:blue"), (0.15, "vertical", "tab:orange")):
        valid = [p.valid[screen] for p in report.poses]
        rates.errorbar(
            position + offset,
            [r.rate for r in valid],
            fmt="o",
            color=colour,
            capsize=3,
            yerr=[[r.rate - r.low for r in valid], [r.high - r.rate for r in valid]],
            label=f"{screen} valid",
        )
        rates.scatter(
            position + offset,
            [p.lit[screen].rate for p in report.poses],
            marker="_",
            s=120,
            color=colour,
            label=f"{screen} lit",
        )
    rates.set_xticks(position, [p.pose for p in report.poses])
    rates.set_ylim(-0.05, 1.05)
    rates.set_ylabel("rate (of the readings)")
    rates.legend(fontsize=6)
    table = report.table
    slots = [(p, k) for p in report.poses for k in range(3)]
    for slot, (p, k) in enumerate(slots):
        column = f"{AXIS_NAMES[k]}_mm"
        rows = table[table["pose"] == p.pose]
        values = (rows[column].dropna() - p.commanded_mm[k]).to_numpy() if column in rows else np.array([])
        colour = ("tab:red", "tab:green", "tab:purple")[k]
        if len(values):
            errors.scatter(np.full(len(values), slot), values, s=12, color=colour, alpha=0.7)
        else:
            errors.annotate(NO_READING, (slot, 0.0), rotation=90, fontsize=6, ha="center", va="center", color="0.4")
    errors.axhline(0.0, color="0.6", lw=0.8)
    errors.set_xticks(range(len(slots)), [f"{p.pose} {AXIS_NAMES[k]}" for p, k in slots], rotation=90, fontsize=6)
    errors.set_ylabel("reading − command (mm)")
    return Plot(
        f"Per pose: each screen's valid rate with its Wilson interval (z = {report.coverage_factor:g}) and "
        "its lit rate "
        f"(bars); every stored reading minus its command per axis ({NO_READING}: no screen measured that "
        "axis at that pose).",
        figure,
    )


def recompute_grid_positioning(report: GridPositioningReport) -> str:
    """The commands that give every figure again from the store or the raw-data CSV."""
    run_id = report.run.id
    return (
        f"bench export {run_id} --kind pose --store {report.store_path} --out run{run_id}.csv, then bench analyze "
        f"grid-positioning run{run_id}.csv --k {report.coverage_factor:g} --json (or on the raw-data file below, "
        "the same rows at full precision)"
    )


def grid_positioning_document(
    report: GridPositioningReport,
    raw: list[RawData],
    *,
    operator: str = "—",
    laboratory: str = "—",
) -> Document:
    config = report.run.config
    test = (
        "Delta thesis §8.4.2"
        if _thesis(report.run)
        else f"{report.run.protocol_name} (ISO 9283 pose test) with partial readings"
    )
    method = (
        f"{test}: {config.get('cycles', '—')} readings at each pose, unidirectional order, read "
        "by the laser grid. Each capture decodes both screens against the commanded position (the only prior); "
        "a screen that decodes measures its two axes (horizontal x, y; vertical y, z), one that does not "
        "(no hit, ambiguous, fault) measures nothing and its axes are absent, never filled. Per axis, over the "
        "readings that measured it: n, AP = x̄ − x_c (ISO 9283 7.2.1 on one axis), 3 S with S the sample "
        "standard deviation (n − 1), and the thesis's max |x_j − x_c| and mean |x_j − x_c|; AP_P and RP_l "
        "(ISO 9283 7.2.1/7.2.2) over the readings with all three axes. Rates k / n with the Wilson score "
        f"interval at z = {report.coverage_factor:g}."
    )
    return assemble(
        report,
        raw,
        operator=operator,
        laboratory=laboratory,
        method=method,
        conditions=conditions_section(
            report,
            ("poses", "cycles", "settle_s", "warmup_s", "ambient_c"),
            (("time base", str(report.run.settings.get("time_base", "not stated"))),),
        ),
        results=_results(report),
        plots=[grid_positioning_plot(report)],
        decision=decision_section(report, NO_CRITERION),
        scope=SCOPE if _thesis(report.run) else ISO_SCOPE,
        recompute=recompute_grid_positioning(report),
    )


#: What ``--criterion`` judges in a laser-grid positioning report: spatial AP and RP of every pose over its
#: complete readings (no U stated; a pose without the readings a figure needs is left out).
CHARACTERISTICS = {
    "AP_mm": Characteristic(
        "spatial AP_P of every pose (complete readings)",
        lambda report: [(p.pose, p.statistics.ap_mm, None) for p in report.poses if p.statistics.ap_mm is not None],
    ),
    "RP_mm": Characteristic(
        "RP_l of every pose (complete readings)",
        lambda report: [(p.pose, p.statistics.rp_mm, None) for p in report.poses if p.statistics.rp_mm is not None],
    ),
}
