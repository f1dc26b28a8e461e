"""The report as a neutral document (sections of paragraphs, tables and figures) that both renderers print.

The HTML template and the PDF builder walk the same :class:`Document`, so the two formats carry the same text,
the same tables and the same figures by construction. Layout follows iso9283.md §9 (identification, device,
method with the deviations table, conditions, instruments, results, plots, decision, raw data, scope). Numbers
with an uncertainty are printed ``value ± U`` with U to two significant digits and the value to the same decimal
place (:mod:`bench.metrology.formatting`, the one rule of every output), k stated in the table heading; lengths
without an uncertainty of their own (budget components) to 0.1 µm (``0.1234``).
"""

from __future__ import annotations

from typing import Any

from bench.metrology.formatting import format_length, format_measured, format_uncertainty, format_value, pose_label
from bench.reports.blocks import Block, Document, Figure, Paragraph, RawData, Section, Table
from bench.reports.content import ReportBase, RunReport, ap_instrument_u_mm, axes_statement
from bench.reports.differences import NO_DIFFERENCE, configuration_differences
from bench.reports.orientation import orientation_blocks
from bench.reports.plots import comparison_plot, report_plots
from bench.reports.signature import PLACEHOLDER_SHOWN, is_placeholder
from bench.robot_kinds import ROBOT_KINDS

__all__ = [
    "Document",
    "Figure",
    "Paragraph",
    "RawData",
    "Section",
    "Table",
    "assemble",
    "comparison_document",
    "conditions_section",
    "decision_blocks",
    "fmt_mm",
    "fmt_pm",
    "key_values",
    "pose_rows",
    "reading_formatter",
    "recompute_command",
    "run_document",
]

SCOPE = (
    "Tested following the methods of ISO 9283:1998, with the deviations listed in the deviations table. "
    "Results are ISO 9283-style; this is not an ISO 9283 certification."
)


def fmt_mm(value: float, resolution_mm: float | None = None) -> str:
    """A length without an uncertainty of its own: to 1 µm, never finer than the readings' ``resolution_mm``
    (:func:`bench.metrology.formatting.format_length`)."""
    return format_length(value, resolution=resolution_mm)


def reading_formatter(report: ReportBase):
    """``mm(value, signed=False)`` for the figures of ``report`` without a U of their own: to 1 µm, never finer than
    its readings' resolution (``report.instrument.resolution_mm``: 0.01 mm calliper readings -> 2 decimals)."""
    resolution = getattr(report.instrument, "resolution_mm", None)

    def mm(value: float, signed: bool = False) -> str:
        return format_length(value, resolution=resolution, signed=signed)

    return mm


def fmt_pm(measured) -> str:
    """``value ± U`` rounded by the uncertainty (:func:`bench.metrology.formatting.format_measured`)."""
    return format_measured(measured.value, measured.expanded_uncertainty)


def _pairs(mapping: dict[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    rows = []
    for key, value in mapping.items():
        if isinstance(value, dict):
            rows.extend(_pairs(value, f"{prefix}{key}."))
        else:
            rows.append((f"{prefix}{key}", "—" if value is None else str(value)))
    return rows


def key_values(ident: str, rows, caption: str = "") -> Table:
    return Table(ident, ("Item", "Value"), tuple((str(k), str(v)) for k, v in rows), caption)


def _identification(report: ReportBase, operator: str, laboratory: str) -> Section:
    run = report.run
    rows = [
        ("Report ID", report.report_id),
        ("Generated (UTC)", report.generated_utc),
        ("Operator", operator),
        ("Laboratory", laboratory),
        ("Run", f"{run.id}" + (f" (campaign {run.campaign})" if run.campaign else "")),
        ("Run started / ended (UTC)", f"{run.started_utc} / {run.ended_utc or '—'}"),
        ("Run status", run.status + (f": {run.reason}" if run.reason else "")),
        ("Protocol", f"{run.protocol_name} v{run.protocol_version}"),
        ("Software (run)", f"bench {run.software_version}, git {run.git_sha}"),
        ("Software (report)", f"bench {report.report_software_version}"),
        ("Configuration SHA-256", report.config_sha256),
        ("Calibrations SHA-256", report.calibration_sha256),
    ]
    return Section("1. Identification", (key_values("identification", rows),))


#: Robot settings that matter for the result (shown in the device section); the rest go to the appendix.
_ROBOT_SHOWN = {
    "firmware.firmware_version": "Firmware version",
    "firmware.device": "Controller",
    "fixture": "Fixture",
    "rated_speed_steps_s": "Rated speed (steps/s)",
    "speed_steps_s": "Speed used (steps/s)",
    "rated_velocity_mm_s": "Rated velocity (mm/s)",
    "firmware": "Firmware",
}
#: Instrument settings that matter for the result (shown in the instruments section); the rest go to the appendix.
_INSTRUMENT_SHOWN = {
    "instrument": "Instrument",
    "cpi": "Resolution (counts per inch)",
    "noise_counts": "Count noise (counts, 1σ)",
    "report_rate_hz": "Report rate (Hz)",
    "calibration_id": "Calibration",
    "u_mm": "Standard uncertainty per axis (mm)",
    "mpe_mm": "Maximum permissible error (mm)",
    "readings": "Readings",
    "model": "Model",
}


def _shown(mapping: dict[str, Any], names: dict[str, str]) -> list[tuple[str, str]]:
    """The settings of ``mapping`` named in ``names`` (flattened keys), with their readable names, in that order."""
    flat = dict(_pairs(mapping))
    return [(label, flat[key]) for key, label in names.items() if key in flat]


def settings_appendix(report: ReportBase) -> Section:
    """Every stored setting of the robot and the instrument, for traceability (the sections show those that matter)."""
    settings = report.run.settings
    rows = [
        *_pairs(settings.get("robot") or {}, "robot."),
        *_pairs(settings.get("instrument") or {}, "instrument."),
        *_pairs(settings.get("dut") or {}, "dut."),
        *(
            (key, str(value))
            for key, value in settings.items()
            if key not in ("robot", "instrument") and not isinstance(value, dict)
        ),
    ]
    # a station template's sample text ("Operator name") is stored as entered but never printed as if a value
    rows = [
        (key, PLACEHOLDER_SHOWN if value not in ("—", "") and is_placeholder(value) else value) for key, value in rows
    ]
    return Section(
        "Appendix A. All stored settings",
        (
            Paragraph(
                "The complete settings stored with the run, as recorded; the sections above show the ones that "
                "matter for the result."
            ),
            key_values("settings", rows),
        ),
    )


def _device(report: ReportBase) -> Section:
    robot = report.run.settings.get("robot") or {}
    rows = [
        ("Robot", report.run.robot),
        ("Kinematic type", (ROBOT_KINDS[report.run.robot].title if report.run.robot in ROBOT_KINDS else "not stated")),
        (
            "Tool centre point (stored robot setting)",
            robot.get("tcp", "not stored (the measuring point is stated on page 1)"),
        ),
        *_shown(robot, _ROBOT_SHOWN),
    ]
    return Section("2. Device under test", (key_values("device", rows),))


def _deviation_table(report: ReportBase) -> Table:
    rows = tuple((d.clause, d.topic, d.requirement, d.done, d.status, d.effect or "—") for d in report.deviations)
    return Table(
        "deviations",
        ("Clause", "Topic", f"{report.reference} requirement", "What was done", "Status", "Expected effect"),
        rows,
        f"Deviations from {report.reference} (computed from the stored run)",
    )


def _method(report: ReportBase, text: str, scope: str) -> Section:
    return Section("3. Method", (Paragraph(text), Paragraph(scope), _deviation_table(report)))


#: Readable names of the configuration keys a report shows.
CONDITION_NAMES = {
    "loads_kg": "Loads (kg)",
    "velocities_pct": "Velocities (% of rated)",
    "cycles": "Cycles per pose",
    "settle_s": "Dwell after each move (s)",
    "cube_centre_mm": "Test cube centre (mm)",
    "cube_side_mm": "Test cube edge (mm)",
    "plane": "Diagonal plane of the poses",
    "poses": "Poses (mm)",
    "approach_mm": "Approach distance (mm)",
    "warmup_s": "Warm-up (s)",
    "ambient_c": "Ambient temperature (°C)",
}


def _value(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return ", ".join(_value(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def conditions_section(report: ReportBase, keys: tuple[str, ...], extra: tuple[tuple[str, str], ...] = ()) -> Section:
    """The configuration keys ``keys`` the run stored (with a value), under readable names."""
    config = report.run.config
    rows = [(CONDITION_NAMES.get(k, k), _value(config[k])) for k in keys if config.get(k) is not None]
    return Section("4. Conditions", (key_values("conditions", [*rows, *extra]),))


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


def _instruments(report: ReportBase) -> Section:
    info = report.instrument
    blocks: list[Block] = [key_values("instrument", _shown(info.settings, _INSTRUMENT_SHOWN) or _pairs(info.settings))]
    calibrations = tuple((str(c.id), c.name, str(c.version), c.created_utc, c.notes or "—") for c in info.calibrations)
    blocks.append(
        Table(
            "calibrations",
            ("ID", "Name", "Version", "Date (UTC)", "Notes"),
            calibrations or (("—", "no stored calibration in force", "", "", ""),),
            "Calibrations in force",
        )
    )
    budget = [(name, format_uncertainty(u), source) for name, u, source in info.budget]
    if info.sigma_mm is not None:
        budget.append(
            (
                f"combined, per {'axis' if info.rp_floor_mm is not None else 'reading'}",
                format_uncertainty(info.sigma_mm),
                "root sum of squares",
            )
        )
    if info.rp_floor_mm is not None:
        budget.append(
            (
                f"instrument RP floor ({info.dims}-D)",
                format_uncertainty(info.rp_floor_mm),
                "RP a perfect robot would show through this instrument (its noise only)",
            )
        )
    blocks.append(
        Table(
            "budget",
            ("Component", "Standard uncertainty (mm)", "Source"),
            tuple(budget) or (("—", "—", "no length uncertainty stated or derivable"),),
            "Instrument uncertainty budget",
        )
    )
    return Section("5. Instruments", tuple(blocks))


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
                    "AD_p (mm)",
                    "RD (mm)",
                    f"U(AD) (mm, k = {k})",
                    *(f"AD_{a} / RD_{a} (°)" for a in angles),
                ),
                tuple(
                    (
                        d.label,
                        fmt_mm(d.result.commanded_distance_mm),
                        fmt_mm(d.result.mean_distance_mm),
                        format_value(d.result.ad_mm, d.u_ad.expanded_uncertainty),
                        f"± {fmt_mm(d.result.rd_mm)}",
                        format_uncertainty(d.u_ad.expanded_uncertainty),
                        *(
                            f"{ad:+.3f} / ±{rd:.3f}"
                            for ad, rd in (zip(d.orientation.ad_deg, d.orientation.rd_deg) if d.orientation else ())
                        ),
                    )
                    for d in report.distances
                ),
                f"Distance accuracy and repeatability ({report.distances[0].first} ↔ {report.distances[0].second})",
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


def decision_blocks(rule: str, header: tuple[str, ...] = (), verdicts=()) -> tuple[Block, ...]:
    """The decision section's content: the rule, then one row per verdict when there are any."""
    blocks: list[Block] = [Paragraph(f"Decision rule: {rule}.")]
    if verdicts:
        blocks.append(Table("decision", header, tuple(verdicts)))
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


def _raw(raw: list[RawData], notes: tuple[str, ...], recompute: str) -> Section:
    rows = tuple((r.name, r.sha256, str(r.rows)) for r in raw)
    blocks: list[Block] = [
        Paragraph(f"Every number above can be recomputed from these files: {recompute}.", verbatim=True),
        Table("rawdata", ("File", "SHA-256", "Rows"), rows, "Raw data"),
    ]
    excluded = notes or ("no sample excluded",)
    blocks.append(Paragraph("Excluded or incomplete data: " + "; ".join(excluded) + "."))
    return Section("9. Raw data", tuple(blocks))


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


def assemble(
    report: ReportBase,
    raw: list[RawData],
    *,
    operator: str,
    laboratory: str,
    method: str,
    scope: str,
    conditions: Section,
    results: tuple[Block, ...],
    plots,
    decision: tuple[Block, ...],
    recompute: str,
) -> Document:
    """One run's report in the order of iso9283.md §9, whatever the protocol: identification, device, method and
    deviations, conditions, instruments, results, plots, decision, raw data with the recomputing command, scope."""
    return Document(
        title=report.title,
        subtitle=f"Report {report.report_id} (stored run {report.run.id})",
        sections=(
            _identification(report, operator, laboratory),
            _device(report),
            _method(report, method, scope),
            conditions,
            _instruments(report),
            Section("6. Results", tuple(results)),
            Section("7. Plots", tuple(Figure(p) for p in plots)),
            Section("8. Decision", tuple(decision)),
            _raw(raw, report.notes, recompute),
            Section("10. Statement of scope", (Paragraph(scope),)),
            settings_appendix(report),
        ),
        meta={"report_id": report.report_id},
    )


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
    ident = [
        ("Configuration ID", first.report_id, second.report_id),
        ("Protocol", a.protocol_name, b.protocol_name),
        ("Robot", a.robot, b.robot),
        ("Status", a.status, b.status),
        ("Started (UTC)", a.started_utc, b.started_utc),
        ("Git SHA", a.git_sha, b.git_sha),
        ("Configuration SHA-256", first.config_sha256[:16], second.config_sha256[:16]),
        ("Calibration ids", str(list(a.calibration_ids)), str(list(b.calibration_ids))),
    ]
    differ = configuration_differences(first, second)
    deviations = tuple(
        (d.clause, d.topic, f"{d.status}: {d.done}", f"{e.status}: {e.done}")
        for d, e in zip(first.deviations, second.deviations)
    )
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
            Section(
                "1. Identification",
                (Table("identification", ("Item", f"A: run {a.id}", f"B: run {b.id}"), tuple(ident)),),
            ),
            Section(
                "2. Conditions that differ",
                (
                    Table(
                        "conditions",
                        ("Parameter", "A", "B"),
                        differ or (("—", NO_DIFFERENCE, ""),),
                        "Configuration, settings and calibrations in force",
                    ),
                ),
            ),
            Section(
                "3. Deviations from ISO 9283",
                (Paragraph(SCOPE), Table("deviations", ("Clause", "Topic", "A", "B"), deviations)),
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
