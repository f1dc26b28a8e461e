"""The pose run's document (ISO 9283 7.2: AP, RP and the figures that go with them) and two pose runs side by side;
laid out with the shared sections of :mod:`bench.reports.document`."""

from __future__ import annotations

from bench.metrology.formatting import format_measured, format_uncertainty, format_value, pose_label
from bench.reports.blocks import Block, Document, Figure, Paragraph, RawData, Section, Table
from bench.reports.compare import comparison_head, paired_deviations
from bench.reports.content import RunReport, axes_statement
from bench.reports.document import (
    SCOPE,
    _raw,
    assemble,
    conditions_section,
    decision_blocks,
    fmt_mm,
    fmt_pm,
)
from bench.reports.instrument import ap_instrument_u_mm
from bench.reports.orientation import orientation_blocks
from bench.reports.pose_plots import comparison_plot, report_plots

__all__ = ["comparison_document", "pose_rows", "recompute_command", "run_document"]


_POSE_CONDITIONS = (
    "loads_kg",
    "velocities_pct",
    "cycles",
    "settle_s",
    "cube_centre_mm",
    "cube_side_mm",
    "plane",
    "poses",
    "approach_mm",
    "warmup_s",
    "ambient_c",
)


def pose_rows(report: RunReport) -> tuple[tuple[str, ...], tuple[tuple[str, ...], ...]]:
    """Header and rows of the per-pose results table."""
    angles = report.poses[0].angle_names if report.poses else ()
    header = (
        "Pose",
        "n",
        "Command x, y, z (mm)",
        "AP_P ± U (mm)",
        "AP_x (mm)",
        "AP_y (mm)",
        "AP_z (mm)",
        "RP_l ± U (mm)",
        "RP floor (mm)",
        *(f"AP_{a} / RP_{a} (°)" for a in angles),
    )
    floor = format_uncertainty(report.instrument.rp_floor_mm) if report.instrument.rp_floor_mm is not None else "—"
    rows = []
    for r in report.poses:
        u_ap = r.ap_u.expanded_uncertainty
        measured = dict(zip(r.axis_names, r.accuracy.ap_axes_mm))
        axes = [format_value(measured[a], u_ap, signed=True) if a in measured else "not measured" for a in "xyz"]
        orientation = ()
        if r.orientation_accuracy is not None:
            orientation = tuple(
                f"{ap:+.3f} / ±{rp:.3f}"
                for ap, rp in zip(r.orientation_accuracy.ap_deg, r.orientation_repeatability.rp_deg)
            )
        rows.append(
            (
                pose_label(r.pose, r.conditions),
                str(r.accuracy.n),
                ", ".join(f"{v:g}" for v in r.commanded_mm),
                fmt_pm(r.ap_u),
                *axes,
                fmt_pm(r.rp_u),
                floor,
                *orientation,
            )
        )
    return header, tuple(rows)


def _results(report: RunReport) -> tuple[Block, ...]:
    header, rows = pose_rows(report)
    k = f"{report.coverage_factor:g}"
    axes = axes_statement(report)
    blocks: list[Block] = [
        Table(
            "results",
            header,
            rows,
            f"Results per pose (U: expanded uncertainty, k = {k}; "
            f"AP axes signed, barycentre − command" + (f". {axes}" if axes else "") + ")",
        )
    ]
    blocks.extend(orientation_blocks(report))
    if report.distances:
        angles = report.distances[0].angle_names
        blocks.append(
            Table(
                "distance",
                (
                    "Pair / conditions",
                    "D_c (mm)",
                    "D̄ (mm)",
                    "AD_p ± U (mm)",
                    "RD ± U (mm)",
                    *(f"AD_{a} / RD_{a} (°)" for a in angles),
                ),
                tuple(
                    (
                        d.label,
                        fmt_mm(d.result.commanded_distance_mm),
                        fmt_mm(d.result.mean_distance_mm),
                        fmt_pm(d.u_ad),
                        fmt_pm(d.u_rd),
                        *(
                            f"{ad:+.3f} / ±{rd:.3f}"
                            for ad, rd in (zip(d.orientation.ad_deg, d.orientation.rd_deg) if d.orientation else ())
                        ),
                    )
                    for d in report.distances
                ),
                f"Distance accuracy and repeatability ({report.distances[0].first} ↔ {report.distances[0].second}); "
                f"U for the coverage of k = {k} (U(AD): Student's k at ν_eff; U(RD): the chi pivot of the spread), "
                f"values rounded by their U as bench analyze distance prints them; {report.distances[0].budget}",
            )
        )
    if report.multidirectional:
        angles = report.multidirectional[0].angle_names
        blocks.append(
            Table(
                "vap",
                ("Pose", "Directions", "vAP_p (mm)", *(f"vAP_{a} (°)" for a in angles)),
                tuple(
                    (
                        v.label,
                        ", ".join(v.directions),
                        fmt_mm(v.result.vap_mm),
                        *(f"{d:.3f}" for d in (v.orientation.vap_deg if v.orientation else ())),
                    )
                    for v in report.multidirectional
                ),
                "Multi-directional pose accuracy variation (ISO 9283 7.2.3)",
            )
        )
    if report.payload:
        rows = []
        for p in report.payload:
            for load, shift, norm in zip(p.result.load_kg, p.result.shift_mm, p.result.shift_norm_mm):
                rows.append((p.label, f"{load:g}", ", ".join(fmt_mm(v) for v in shift), fmt_mm(norm)))
        blocks.append(
            Table(
                "payload",
                ("Pose", "Load (kg)", "PE(m) x, y, z (mm)", "|PE(m)| (mm)"),
                tuple(rows),
                f"Payload error (project definition, reference load "
                f"{report.payload[0].result.reference_load_kg:g} kg; not an ISO 9283 term)",
            )
        )
    return tuple(blocks)


def _decision(report: RunReport) -> tuple[Block, ...]:
    return decision_blocks(
        report.decision.rule,
        ("Project criterion", "Pose", "Value ± U (mm)", "Limit (mm)", "Result"),
        [
            (f"{name} (project criterion)", label, format_measured(value, u), f"{limit:g}", result)
            for name, label, value, u, limit, result in report.decision.verdicts
        ],
    )


def recompute_command(report: RunReport) -> str:
    """The CLI call that recomputes the per-pose results from the raw-data CSV."""
    # the same instrument term as the report's U(AP): the reading's u and the registrations' (a relative instrument)
    u_mm = ap_instrument_u_mm(report.instrument.sigma_mm, report.run)
    declared = "" if u_mm is None else f" --instrument-u-mm {u_mm:.6g}"
    command = f"bench analyze iso9283 FILE.csv{declared} --k {report.coverage_factor:g}"
    if report.orientation:  # the tilt readings' own file and gauge
        g = report.tilt_gauge
        command += (
            f"; orientation: bench analyze orientation run{report.run.id}_tilts.csv --spacing-mm "
            f"{g.spacing_mm:g} --u-spacing-mm {g.u_spacing_mm:.6g} --resolution-mm {g.resolution_mm:g} "
            f"--mpe-mm {g.mpe_mm:g} --bias-deg {g.bias_deg:g} --u-bias-deg {g.u_bias_deg:g} "
            f"--k {report.coverage_factor:g}"
        )
    return command


def run_document(report: RunReport, raw: list[RawData], *, operator: str = "—", laboratory: str = "—") -> Document:
    """The document of one pose run's report."""
    clauses = "; ".join(report.clauses) or "none"
    robot = report.run.settings.get("robot") or {}
    return assemble(
        report,
        raw,
        operator=operator,
        laboratory=laboratory,
        method=f"Standard: ISO 9283:1998. Clauses applied: {clauses}. Formulas of ISO 9283:1998 7.2 (sample "
        f"standard deviation with n − 1; AP against the commanded pose); uncertainties after the GUM "
        f"(JCGM 100:2008).",
        scope=SCOPE,
        conditions=conditions_section(
            report, _POSE_CONDITIONS, (("velocity (mm/s)", str(robot.get("rated_velocity_mm_s", "not stated"))),)
        ),
        results=_results(report),
        plots=report_plots(report),
        decision=_decision(report),
        recompute=recompute_command(report),
    )


def comparison_document(first: RunReport, second: RunReport, raw: list[RawData]) -> Document:
    """Two runs side by side: identification, differing conditions, deviations, paired results, plot."""
    a, b = first.run, second.run
    second_poses = {r.label: r for r in second.poses}
    paired = []
    for r in first.poses:
        s = second_poses.get(r.label)
        if s is None:
            continue
        u_ap = max(r.ap_u.expanded_uncertainty, s.ap_u.expanded_uncertainty)
        u_rp = max(r.rp_u.expanded_uncertainty, s.rp_u.expanded_uncertainty)
        paired.append(
            (
                pose_label(r.pose, r.conditions),
                fmt_pm(r.ap_u),
                fmt_pm(s.ap_u),
                format_value(s.accuracy.ap_mm - r.accuracy.ap_mm, u_ap, signed=True),
                fmt_pm(r.rp_u),
                fmt_pm(s.rp_u),
                format_value(s.repeatability.rp_mm - r.repeatability.rp_mm, u_rp, signed=True),
            )
        )
    runs = f"run {a.id} (A) and run {b.id} (B)"
    return Document(
        title=f"Comparison of {runs}",
        subtitle=f"Runs {a.id} (A) and {b.id} (B)",
        sections=(
            *comparison_head(first, second),
            Section(
                "3. Deviations from ISO 9283",
                (
                    Paragraph(SCOPE),
                    Table("deviations", ("Clause", "Topic", "A", "B"), paired_deviations(first, second)),
                ),
            ),
            Section(
                "4. Results",
                (
                    Table(
                        "results",
                        (
                            "Pose",
                            "AP_P ± U A (mm)",
                            "AP_P ± U B (mm)",
                            "ΔAP (B − A)",
                            "RP_l ± U A (mm)",
                            "RP_l ± U B (mm)",
                            "ΔRP (B − A)",
                        ),
                        tuple(paired),
                        f"Poses present in both runs, U with k = {first.coverage_factor:g}",
                    ),
                    Figure(comparison_plot(first, second)),
                ),
            ),
            _raw(raw, first.notes + second.notes, "see each run's own report"),
        ),
        meta={"report_id": f"{first.report_id}_vs_{second.report_id}"},
    )
