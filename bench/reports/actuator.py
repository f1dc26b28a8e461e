"""The report of an ``actuator_accuracy`` run: the dissertation's actuator test (000 §8.4) with the bias it hides
and ISO 230-2 unidirectional figures (iso9283.md §7.1, §7.4); for a bidirectional run (``approach =
"bidirectional"``) also the ISO 230-2 bidirectional figures: reversal B, repeatability R, systematic error E, M and
accuracy A per actuator, and B_i per target.

Every figure comes from :func:`bench.metrology.actuator_tables.analyze_actuators` on the run's tidy
``actuator_travel`` table, the same call ``bench analyze actuator FILE.csv --robot pkm5`` makes on the raw-data
CSV the report writes; the control resolution is the robot model's mm per step (000 Eq. 8.1,
:func:`~bench.metrology.actuator_tables.robot_control_resolution`). In a bidirectional run those figures use the
approaches from below (the dissertation's), and the bidirectional ones come from
:func:`bench.metrology.bidirectional_tables.analyze_bidirectional` on the same table (``bench analyze iso230-2
FILE.csv``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.metrology.actuator_tables import (
    ActuatorResult,
    actuator_table,
    analyze_actuators,
    robot_control_resolution,
)
from bench.metrology.bidirectional_tables import BidirectionalResult, analyze_bidirectional
from bench.reports.bidirectional import bidirectional_plot
from bench.reports.content import ReportBase, calibrations_in_force, provenance, run_table
from bench.reports.criteria import Characteristic, decision_section
from bench.reports.deviations_bench import actuator_deviations
from bench.reports.document import (
    Block,
    Document,
    Paragraph,
    RawData,
    Table,
    assemble,
    conditions_section,
    fmt_mm,
    fmt_pm,
    reading_formatter,
)
from bench.reports.instrument import reading_instrument, uncertainty_stated
from bench.reports.plots import Plot, panels
from bench.store import Store

__all__ = ["ActuatorReport", "actuator_document", "actuator_plot", "collect_actuator", "recompute_actuator"]

SCOPE = (
    "Tested following the actuator test of the dissertation (000 §8.4, after Groover) and reporting ISO 230-2 "
    "unidirectional figures, with the deviations listed in the deviations table. This is not an ISO 230-2 "
    "acceptance test."
)
BIDIRECTIONAL_SCOPE = (
    "Tested following ISO 230-2's bidirectional positioning test on single actuators, and reporting "
    "the dissertation's actuator figures (000 §8.4, after Groover) on the approaches from below, with "
    "the deviations listed in the deviations table. This is not an ISO 230-2 acceptance test."
)
NO_CRITERION = (
    "no acceptance criterion stated: no pass/fail statement (000 §8.4 and ISO 230-2 define methods, not grades)"
)


@dataclass(frozen=True, kw_only=True)
class ActuatorReport(ReportBase):
    """Everything the report of an actuator_accuracy run prints."""

    actuators: tuple[ActuatorResult, ...]
    #: ISO 230-2 bidirectional figures per actuator; empty unless the run approached the targets both ways
    bidirectional: tuple[BidirectionalResult, ...] = ()


def collect_actuator(
    store: Store, run_id: int, *, k: float = 2.0, resamples: int = 1000, allow_unknown: bool = False
) -> ActuatorReport:
    """Gather the facts and figures of the report of ``actuator_accuracy`` run ``run_id``."""
    run = store.run(run_id)
    table = run_table(store, run_id, "actuator_travel")
    calibrations = calibrations_in_force(store, run)
    instrument = reading_instrument(run, calibrations, table["travel_mm"], difference=True)
    results = analyze_actuators(
        actuator_table(table),
        control_resolution_mm=robot_control_resolution(run.robot),
        instrument_u_mm=instrument.sigma_mm or 0.0,
        k=k,
    )
    both_ways = "direction" in table.columns and bool((table["direction"] < 0).any())
    bidirectional = tuple(analyze_bidirectional(table)) if both_ways else ()
    deviations = actuator_deviations(
        config=run.config,
        settings=run.settings,
        repeats_measured=min(r.groover.n for r in results),
        instrument_sigma_mm=instrument.sigma_mm,
        uncertainty_stated=uncertainty_stated(instrument),
        allow_unknown=allow_unknown,
    )
    base = provenance(run, calibrations)
    dropped = tuple(
        f"actuator {r.actuator}: {r.dropped} readings of repeats missing a travel left out"
        for r in results
        if r.dropped
    )
    return ActuatorReport(
        **{**base, "notes": base["notes"] + dropped},
        title=run.config.get("title") or "Linear-actuator accuracy and repeatability (000 §8.4)",
        reference="000 §8.4 / ISO 230-2",
        clauses=(
            "000 §8.4, Eqs. 8.1-8.3: repeatability ±3σ̄, accuracy CR/2 + 3σ̄ (after Groover)",
            "ISO 230-2 unidirectional R↑, E↑, A↑ (iso9283.md §7.1 [U])",
        )
        + (("ISO 230-2 bidirectional reversal B, repeatability R, E, M, accuracy A",) if bidirectional else ()),
        deviations=tuple(deviations),
        instrument=instrument,
        table=table,
        coverage_factor=k,
        actuators=results,
        bidirectional=bidirectional,
    )


def _with_u(value: float, measured) -> str:
    return fmt_mm(value) + " (no U: < 3 repeats)" if measured is None else fmt_pm(measured)


def _results(report: ActuatorReport) -> tuple[Block, ...]:
    mm = reading_formatter(report)
    k = f"{report.coverage_factor:g}"
    summary = tuple(
        (
            r.actuator,
            str(r.groover.n),
            ", ".join(f"{t:g}" for t in r.targets_mm),
            f"{r.control_resolution_mm:g}",
            _with_u(r.groover.repeatability_mm, r.repeatability_u),
            _with_u(r.groover.accuracy_mm, r.accuracy_u),
            mm(r.groover.max_abs_bias_mm),
            mm(r.iso230_2.repeatability_forward_mm),
            mm(r.iso230_2.systematic_forward_mm),
            mm(r.iso230_2.accuracy_forward_mm),
        )
        for r in report.actuators
    )
    targets = tuple(
        (r.actuator, f"{t:g}", str(r.groover.n), mm(float(r.readings_mm[:, i].mean())), fmt_pm(u), mm(s), mm(4.0 * s))
        for r in report.actuators
        for i, (t, u, s) in enumerate(zip(r.targets_mm, r.bias_u, r.groover.sigma_mm))
    )
    return (
        Table(
            "actuators",
            (
                "Actuator",
                "n",
                "Targets (mm)",
                "CR (mm/step)",
                "Repeatability ±3σ̄ ± U (mm)",
                "Accuracy CR/2 + 3σ̄ ± U (mm)",
                "max |bias| (mm)",
                "R↑ (mm)",
                "E↑ (mm)",
                "A↑ (mm)",
            ),
            summary,
            f"Per actuator: 000 Eqs. 8.1-8.3 (after Groover) and ISO 230-2 unidirectional figures "
            f"(U: expanded uncertainty, k = {k}, bootstrap over whole repeats)",
        ),
        Table(
            "actuator-targets",
            (
                "Actuator",
                "Target P_i (mm)",
                "n",
                "Mean travel x̄_i (mm)",
                "Bias x̄_i − P_i ± U (mm)",
                "s_i (mm)",
                "R_i↑ = 4 s_i (mm)",
            ),
            targets,
            f"Per actuator and target (U of the bias: k = {k}, √(s_i²/n + u_gauge²))",
        ),
        Paragraph(
            "Groover's accuracy CR/2 + 3σ̄ assumes that the mean travel lands on the target; the bias column "
            "and max |bias| show the systematic error it leaves out (iso9283.md §7.4)."
        ),
        *_bidirectional_results(report),
    )


def _bidirectional_results(report: ActuatorReport) -> tuple[Block, ...]:
    """The ISO 230-2 bidirectional tables of a bidirectional run (none otherwise)."""
    mm = reading_formatter(report)
    if not report.bidirectional:
        return ()
    axes = tuple(
        (
            r.axis,
            f"{r.forward_mm.shape[0]} / {r.backward_mm.shape[0]}",
            mm(r.result.reversal_max_mm),
            mm(r.result.repeatability_forward_mm),
            mm(r.result.repeatability_backward_mm),
            mm(r.result.repeatability_mm),
            mm(r.result.systematic_mm),
            mm(r.result.mean_bidirectional_mm),
            mm(r.result.accuracy_mm),
        )
        for r in report.bidirectional
    )
    targets = tuple(
        (r.axis, f"{t:g}", mm(up, True), mm(down, True), mm(b, True), mm(float(s_up)), mm(float(s_down)))
        for r in report.bidirectional
        for t, up, down, b, s_up, s_down in zip(
            r.targets_mm,
            r.result.mean_deviation_forward_mm,
            r.result.mean_deviation_backward_mm,
            r.result.reversal_mm,
            (r.forward_mm - r.targets_mm).std(axis=0, ddof=1),
            (r.backward_mm - r.targets_mm).std(axis=0, ddof=1),
        )
    )
    return (
        Table(
            "actuator-bidirectional",
            ("Actuator", "n ↑ / ↓", "B (mm)", "R↑ (mm)", "R↓ (mm)", "R (mm)", "E (mm)", "M (mm)", "A (mm)"),
            axes,
            "ISO 230-2 bidirectional figures per actuator: reversal B = max |B_i|, repeatability R = max_i "
            "max(2s_i↑ + 2s_i↓ + |B_i|, R_i↑, R_i↓), systematic error E, mean bidirectional error M, accuracy A",
        ),
        Table(
            "actuator-reversal",
            (
                "Actuator",
                "Target P_i (mm)",
                "x̄_i↑ − P_i (mm)",
                "x̄_i↓ − P_i (mm)",
                "B_i = x̄_i↑ − x̄_i↓ (mm)",
                "s_i↑ (mm)",
                "s_i↓ (mm)",
            ),
            targets,
            "Per actuator and target: mean deviation of each approach direction, the reversal and the spreads",
        ),
    )


def actuator_plot(report: ActuatorReport) -> Plot:
    """Per actuator: every reading minus its target, the mean bias with U and the x̄ ± 2s band (ISO 230-2's A↑)."""
    figure, axes_list = panels(len(report.actuators), max_columns=3, size=(3.4, 2.8))
    for axes, r in zip(axes_list, report.actuators):
        targets = np.asarray(r.targets_mm)
        deviation = r.readings_mm - targets
        bias = np.array(r.groover.mean_deviation_mm)
        sigma = np.array(r.groover.sigma_mm)
        axes.axhline(0.0, color="0.6", lw=0.8)
        axes.scatter(
            np.broadcast_to(targets, deviation.shape), deviation, s=6, color="tab:blue", alpha=0.5, label="readings"
        )
        axes.errorbar(
            targets,
            bias,
            yerr=[u.expanded_uncertainty for u in r.bias_u],
            fmt="o-",
            color="tab:red",
            ms=3,
            capsize=2,
            lw=1,
            label="bias ± U",
        )
        axes.plot(targets, bias + 2 * sigma, ls="--", color="0.4", lw=0.8, label="x̄ ± 2s")
        axes.plot(targets, bias - 2 * sigma, ls="--", color="0.4", lw=0.8)
        axes.set_title(f"actuator {r.actuator}", fontsize=8)
        axes.set_xlabel("commanded travel (mm)", fontsize=7)
        axes.set_ylabel("reading − command (mm)", fontsize=7)
        axes.tick_params(labelsize=7)
    axes_list[0].legend(fontsize=5)
    return Plot(
        f"Actuator bias against commanded travel: every reading minus its target, the mean bias with U "
        f"(k = {report.coverage_factor:g}) and the x̄ ± 2s band of ISO 230-2's A↑.",
        figure,
    )


def recompute_actuator(report: ActuatorReport) -> str:
    """The CLI call that recomputes every actuator figure from the raw-data CSV."""
    sigma = report.instrument.sigma_mm or 0.0
    both = (
        (
            f"; bench analyze iso230-2-run {report.run.id} --json (or bench analyze iso230-2 FILE.csv --json) for the "
            "bidirectional figures"
        )
        if report.bidirectional
        else ""
    )
    return (
        f"bench analyze actuator FILE.csv --robot {report.run.robot} --instrument-u-mm {sigma:.6g} --k "
        f"{report.coverage_factor:g}{both} (bench export RUN_ID --kind actuator_travel writes the same table)"
    )


def actuator_document(
    report: ActuatorReport, raw: list[RawData], *, operator: str = "—", laboratory: str = "—"
) -> Document:
    config = report.run.config
    if report.bidirectional:
        return _bidirectional_document(report, raw, operator=operator, laboratory=laboratory)
    method = (
        f"Dissertation 000 §8.4: each actuator, free-standing on the actuator bench, travels "
        f"{', '.join(f'{float(v):g}' for v in config.get('distances_mm', ()))} mm up from a start stroke of "
        f"{config.get('start_mm', '—')} mm where the depth gauge was zeroed, {config.get('repeats', '—')} "
        "repeats, each read by the gauge. CR = the robot model's mm per step (000 Eq. 8.1); σ̄ = mean over "
        "targets of the sample standard deviation (n − 1) at each target; repeatability ±3σ̄ and accuracy "
        "CR/2 + 3σ̄ (000 Eqs. 8.2-8.3); bias x̄_i − P_i. ISO 230-2 (iso9283.md §7.1, from memory [U]): "
        "R↑ = max 4 s_i, E↑ = max x̄_i − min x̄_i of the mean deviations, A↑ = max(x̄_i + 2 s_i) − "
        "min(x̄_i − 2 s_i)."
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
                "fixture",
                "actuators",
                "distances_mm",
                "repeats",
                "start_mm",
                "velocity_pct",
                "settle_s",
                "warmup_s",
                "ambient_c",
            ),
        ),
        results=_results(report),
        plots=[actuator_plot(report)],
        decision=decision_section(report, NO_CRITERION),
        recompute=recompute_actuator(report),
    )


def _bidirectional_document(report: ActuatorReport, raw: list[RawData], *, operator: str, laboratory: str) -> Document:
    config = report.run.config
    method = (
        f"ISO 230-2 linear cycles (iso9283.md §7.1, from memory [U]) on the actuator bench: each actuator, "
        f"free-standing, is zeroed by the depth gauge at {config.get('start_mm', '—')} mm stroke; then "
        f"{config.get('cycles', '—')} times the targets "
        f"{', '.join(f'{float(v):g}' for v in sorted(config.get('distances_mm', ())))} mm above it are "
        "approached in increasing order (↑, from below) and, after an overrun of "
        f"{config.get('overrun_mm', '—')} mm past the highest, in decreasing order (↓, from above), each read "
        "by the gauge. With x_ij = reading − target: x̄_i↑, x̄_i↓ and s_i↑, s_i↓ (n − 1) per target; "
        "B_i = x̄_i↑ − x̄_i↓, B = max |B_i|; R_i = max(2s_i↑ + 2s_i↓ + |B_i|, 4s_i↑, 4s_i↓), R = max R_i; "
        "E = max(x̄_i↑, x̄_i↓) − min(x̄_i↑, x̄_i↓); M = max x̄_i − min x̄_i of the bidirectional means; "
        "A = max(x̄_i↑ + 2s_i↑, x̄_i↓ + 2s_i↓) − min(x̄_i↑ − 2s_i↑, x̄_i↓ − 2s_i↓). The 000 §8.4 figures "
        "(Groover's ±3σ̄ and CR/2 + 3σ̄, the bias) are computed on the approaches from below."
    )
    return assemble(
        report,
        raw,
        operator=operator,
        laboratory=laboratory,
        method=method,
        scope=BIDIRECTIONAL_SCOPE,
        conditions=conditions_section(
            report,
            (
                "fixture",
                "actuators",
                "distances_mm",
                "cycles",
                "start_mm",
                "velocity_pct",
                "settle_s",
                "warmup_s",
                "ambient_c",
            ),
            (
                ("approach", "bidirectional (ISO 230-2 linear cycle)"),
                ("overrun at each reversal (mm)", f"{config.get('overrun_mm', '—')}"),
            ),
        ),
        results=_results(report),
        plots=[actuator_plot(report), bidirectional_plot(report.bidirectional)],
        decision=decision_section(report, NO_CRITERION),
        recompute=recompute_actuator(report),
    )


def _u(measured) -> float | None:
    return None if measured is None else measured.expanded_uncertainty


#: What ``--criterion`` judges in an actuator report (upper limits, per actuator, with the U the report states).
CHARACTERISTICS = {
    "repeatability_mm": Characteristic(
        "repeatability ±3σ̄ of every actuator",
        lambda report: [
            (f"actuator {r.actuator}", r.groover.repeatability_mm, _u(r.repeatability_u)) for r in report.actuators
        ],
    ),
    "accuracy_mm": Characteristic(
        "accuracy CR/2 + 3σ̄ of every actuator",
        lambda report: [(f"actuator {r.actuator}", r.groover.accuracy_mm, _u(r.accuracy_u)) for r in report.actuators],
    ),
}
