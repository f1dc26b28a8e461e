"""The report of a ``mouse_calibration`` run: the x-y mouse's 2x2 matrix with its U, against the stated reference.

The fit is recomputed from the run's raw ``mouse`` samples (and its calliper readings, ``mouse_reference``) by the
same pairing and fit as the stored calibration (:func:`bench.metrology.mouse_calibration.mouse_calibration_moves`,
:func:`bench.metrology.fit_matrix` with an intercept per move direction); the calibration the run stored, and
whether any station put it in force, are named.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bench.metrology import fit_matrix
from bench.metrology.formatting import format_measured, format_uncertainty
from bench.metrology.mouse_calibration import MatrixCalibration, counts_per_inch, mouse_calibration_moves
from bench.reports.content import ReportBase, calibrations_in_force, provenance, run_table
from bench.reports.document import (
    Block,
    Document,
    RawData,
    Table,
    assemble,
    conditions_section,
    decision_blocks,
)
from bench.reports.instrument import InstrumentInfo
from bench.store import Store

__all__ = ["MouseCalibrationReport", "collect_mouse_calibration", "mouse_calibration_document"]

SCOPE = (
    "Optical-mouse resolution calibration following the dissertation's App. A.7 steps, fitted as the 2x2 "
    "least-squares matrix of sensors.md §5.2 with an intercept per move direction; the x-z mouse is not "
    "calibrated by this run."
)


@dataclass(frozen=True, kw_only=True)
class MouseCalibrationReport(ReportBase):
    """Everything the report of a mouse_calibration run prints."""

    fit: MatrixCalibration
    reference_u_pct: float
    stored: Any  #: the calibration record the run stored (None when none was)


def collect_mouse_calibration(
    store: Store, run_id: int, *, k: float = 2.0, resamples: int = 1000, allow_unknown: bool = False
) -> MouseCalibrationReport:
    """Gather the fit of ``mouse_calibration`` run ``run_id`` (``k``, ``resamples``, ``allow_unknown`` unused: the
    matrix's U takes Student's t at the fit's degrees of freedom)."""
    run = store.run(run_id)
    table = run_table(store, run_id, "mouse")
    samples = sorted(store.samples(run_id, kind="mouse"), key=lambda s: s.step_index)
    references = store.samples(run_id, kind="mouse_reference") if run.config.get("reference") == "calliper" else None
    reference, counts, readings = mouse_calibration_moves(samples, references)
    fit = fit_matrix(reference, counts, per_direction=True, readings=readings)
    stored = next((c for c in store.calibrations() if c.name == "mouse" and c.source_run_id == run_id), None)
    calibrations = calibrations_in_force(store, run)
    instrument = InstrumentInfo(dict(run.settings.get("instrument") or {}), None, (), 0, None, calibrations)
    return MouseCalibrationReport(
        **provenance(run, calibrations),
        title=run.config.get("title") or "Optical-mouse resolution calibration",
        reference="000 App. A.7",
        clauses=("000 App. A.7 steps; sensors.md §5.2 2x2 least squares",),
        deviations=(),
        instrument=instrument,
        table=table,
        coverage_factor=fit.coverage_factor,
        fit=fit,
        reference_u_pct=float(run.config.get("reference_u_pct") or 0.0),
        stored=stored,
    )


def _results(report: MouseCalibrationReport) -> tuple[Block, ...]:
    fit, k = report.fit, report.fit.coverage_factor
    a, big_u = fit.a_mm_per_count, fit.expanded_a_mm_per_count
    matrix = tuple(
        (f"sensor {'xy'[i]}", *(format_measured(a[i, j], big_u[i, j], signed=True) for j in range(2))) for i in range(2)
    )
    big_u_scale = k * fit.u_scale_mm_per_count(report.reference_u_pct / 100.0)
    scales = tuple(
        (
            axis,
            format_measured(fit.scale_mm_per_count[j], big_u_scale[j]),
            format_measured(*counts_per_inch(fit.scale_mm_per_count[j], big_u_scale[j])),
            format_uncertainty(fit.sigma_counts[j]),
        )
        for j, axis in enumerate("xy")
    )
    intercepts = tuple(
        (
            label,
            *(
                format_measured(fit.offsets_counts[i, j], k * fit.u_offsets_counts[i, j], signed=True)
                + (" significant" if fit.offsets_significant[i, j] else "")
                for j in range(2)
            ),
        )
        for i, label in enumerate(fit.offset_labels)
    )
    return (
        Table(
            "mouse-matrix",
            ("A (mm/count)", "stage x", "stage y"),
            matrix,
            f"A = B⁻¹ ± U (95 %, Student's k = {k:.2f} at {fit.dof} degrees of freedom), {fit.n} moves; the "
            f"reference's stated scale u ({report.reference_u_pct:g} %) is added to the stored scales",
        ),
        Table(
            "mouse-scales",
            ("Axis", "Scale ± U (mm/count)", "cpi ± U", "Residual SD (counts)"),
            scales,
            f"Scale along each sensor axis ± U (k = {k:.2f}: the fit's u and the reference's scale u, as stored), "
            f"cpi = 25.4 / scale with its U; rotation {fit.rotation_deg:+.3f} deg",
        ),
        Table(
            "mouse-intercepts",
            ("Move direction", "Sensor x (counts)", "Sensor y (counts)"),
            intercepts,
            "Intercept per move direction ± U: a significant one is a start/stop offset, lost counts or backlash, "
            "kept out of A by the fit",
        ),
    )


def _decision(report: MouseCalibrationReport) -> tuple[Block, ...]:
    stored = report.stored
    if stored is None:
        rule = "no calibration was stored from this run (it did not complete)"
    else:
        rule = (
            f"no acceptance criterion; the run stored calibration mouse-v{stored.version}, which a station puts "
            f"in force only by naming it ([mice] calibration = {stored.version})"
        )
    return decision_blocks(rule)


def mouse_calibration_document(
    report: MouseCalibrationReport,
    raw: list[RawData],
    *,
    operator: str = "—",
    laboratory: str = "—",
) -> Document:
    config = report.run.config
    source = {
        "calliper": "calliper readings of the end effector's position against a fixed stop",
        "calibrated-axis": "the commanded travel of an axis stated to be calibrated",
    }
    method = (
        f"Steps of {config.get('distances_mm', '—')} mm along x, then y, {config.get('repeats', '—')} "
        f"repeats; the mouse counts at every reading, the reference from "
        f"{source.get(config.get('reference'), 'the commanded travel (a version 1 run: the robot under test)')}. "
        "Every move between two readings of one axis (both directions) enters the fit c = B r + c0(direction)."
    )
    recompute = (
        f"bench export {report.run.id} --kind mouse (and --kind mouse_reference for a calliper reference), "
        "then bench analyze mouse FILE.csv [--reference REF.csv]"
    )
    keys = ("distances_mm", "repeats", "start_mm", "velocity_pct", "settle_s", "reference", "reference_u_pct")
    return assemble(
        report,
        raw,
        operator=operator,
        laboratory=laboratory,
        method=method,
        scope=SCOPE,
        conditions=conditions_section(report, keys),
        results=_results(report),
        plots=[],
        decision=_decision(report),
        recompute=recompute,
    )
