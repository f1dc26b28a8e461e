"""The report as a neutral document (sections of paragraphs, tables and figures) that both renderers print.

The HTML template and the PDF builder walk the same :class:`Document`, so the two formats carry the same text,
the same tables and the same figures by construction. Layout follows iso9283.md §9 (identification, device,
method with the deviations table, conditions, instruments, results, plots, decision, raw data, scope). Numbers
are formatted here, once: lengths in mm with 4 significant decimals' worth (``0.1234``), expanded uncertainties
as ``value ± U`` with k stated in the table heading.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from bench.reports.content import RunReport
from bench.reports.plots import Plot, comparison_plot, report_plots

__all__ = ["Document", "Figure", "Paragraph", "RawData", "Section", "Table", "comparison_document",
           "pose_rows", "recompute_command", "run_document"]

SCOPE = ("Tested following the methods of ISO 9283:1998, with the deviations listed in the deviations table. "
         "Results are ISO 9283-style; this is not an ISO 9283 certification.")
_KINEMATICS = {"pkm5": "parallel kinematic machine, 5 DOF (x, y, z, α, β)", "delta4": "4-RSS delta, 3 DOF",
               "prus3": "3-PRUS parallel robot, 6 DOF"}


@dataclass(frozen=True)
class Paragraph:
    text: str


@dataclass(frozen=True)
class Table:
    ident: str  #: HTML id, e.g. "results"
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str = ""


@dataclass(frozen=True)
class Figure:
    plot: Plot


Block = Paragraph | Table | Figure


@dataclass(frozen=True)
class Section:
    title: str
    blocks: tuple[Block, ...]


@dataclass(frozen=True)
class RawData:
    """A raw-data file written next to the report."""

    name: str
    sha256: str
    rows: int


@dataclass(frozen=True)
class Document:
    title: str
    subtitle: str
    sections: tuple[Section, ...]
    meta: dict[str, Any] = field(default_factory=dict)


def _mm(value: float) -> str:
    return f"{value:.4f}"


def _pm(measured) -> str:
    return f"{measured.value:.4f} ± {measured.expanded_uncertainty:.4f}"


def _pairs(mapping: dict[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    rows = []
    for key, value in mapping.items():
        if isinstance(value, dict):
            rows.extend(_pairs(value, f"{prefix}{key}."))
        else:
            rows.append((f"{prefix}{key}", "—" if value is None else str(value)))
    return rows


def _key_values(ident: str, rows, caption: str = "") -> Table:
    return Table(ident, ("Item", "Value"), tuple((str(k), str(v)) for k, v in rows), caption)


def _identification(report: RunReport, operator: str, laboratory: str) -> Section:
    run = report.run
    rows = [("Report ID", report.report_id), ("Generated (UTC)", report.generated_utc),
            ("Operator", operator), ("Laboratory", laboratory), ("Run", f"{run.id}" + (
                f" (campaign {run.campaign})" if run.campaign else "")),
            ("Run started / ended (UTC)", f"{run.started_utc} / {run.ended_utc or '—'}"),
            ("Run status", run.status + (f": {run.reason}" if run.reason else "")),
            ("Protocol", f"{run.protocol_name} v{run.protocol_version}"),
            ("Software (run)", f"bench {run.software_version}, git {run.git_sha}"),
            ("Software (report)", f"bench {report.report_software_version}"),
            ("Configuration SHA-256", report.config_sha256),
            ("Calibrations SHA-256", report.calibration_sha256)]
    return Section("1. Identification", (_key_values("identification", rows),))


def _device(report: RunReport) -> Section:
    robot = report.run.settings.get("robot") or {}
    rows = [("Robot", report.run.robot), ("Kinematic type", _KINEMATICS.get(report.run.robot, "not stated")),
            ("Tool centre / measuring point", robot.get("tcp", "not stated (platform centre of the model)")),
            *_pairs(robot, "controller.")]
    return Section("2. Device under test", (_key_values("device", rows),))


def _deviation_table(report: RunReport) -> Table:
    rows = tuple((d.clause, d.topic, d.requirement, d.done, d.status, d.effect or "—") for d in report.deviations)
    return Table("deviations", ("Clause", "Topic", "ISO 9283 requirement", "What was done", "Status",
                                "Expected effect"), rows, "Deviations from ISO 9283 (computed from the stored run)")


def _method(report: RunReport) -> Section:
    clauses = "; ".join(report.clauses) or "none"
    return Section("3. Method", (
        Paragraph(f"Standard: ISO 9283:1998. Clauses applied: {clauses}. Formulas as in bench.metrology "
                  f"(sample standard deviation with n − 1; AP against the commanded pose)."),
        Paragraph(SCOPE), _deviation_table(report)))


def _conditions(report: RunReport) -> Section:
    config = report.run.config
    keys = ("loads_kg", "velocities_pct", "cycles", "settle_s", "cube_centre_mm", "cube_side_mm", "plane",
            "poses", "approach_mm", "warmup_s", "ambient_c")
    rows = [(k, "—" if config.get(k) is None else str(config.get(k))) for k in keys if k in config]
    rows.append(("velocity (mm/s)", str((report.run.settings.get("robot") or {}).get("rated_velocity_mm_s",
                                                                                      "not stated"))))
    return Section("4. Conditions", (_key_values("conditions", rows),))


def _instruments(report: RunReport) -> Section:
    info = report.instrument
    blocks: list[Block] = [_key_values("instrument", _pairs(info.settings))]
    calibrations = tuple((str(c.id), c.name, str(c.version), c.created_utc, c.notes or "—")
                         for c in info.calibrations)
    blocks.append(Table("calibrations", ("ID", "Name", "Version", "Date (UTC)", "Notes"), calibrations or (
        ("—", "no stored calibration in force", "", "", ""),), "Calibrations in force"))
    budget = [(name, _mm(u), source) for name, u, source in info.budget]
    if info.sigma_mm is not None:
        budget.append(("combined, per axis", _mm(info.sigma_mm), "root sum of squares"))
        budget.append((f"instrument RP floor ({info.dims}-D)", _mm(info.rp_floor_mm),
                       "bench.metrology.instrument_rp_floor"))
    blocks.append(Table("budget", ("Component", "Standard uncertainty (mm)", "Source"), tuple(budget),
                        "Instrument uncertainty budget"))
    return Section("5. Instruments", tuple(blocks))


def pose_rows(report: RunReport) -> tuple[tuple[str, ...], tuple[tuple[str, ...], ...]]:
    """Header and rows of the per-pose results table."""
    angles = report.poses[0].angle_names if report.poses else ()
    header = ("Pose", "n", "Command x, y, z (mm)", "AP_P ± U (mm)", "AP_x (mm)", "AP_y (mm)", "AP_z (mm)",
              "RP_l ± U (mm)", "RP floor (mm)", *(f"AP_{a} / RP_{a} (°)" for a in angles))
    floor = _mm(report.instrument.rp_floor_mm) if report.instrument.rp_floor_mm is not None else "—"
    rows = []
    for r in report.poses:
        axes = [_mm(v) for v in r.accuracy.ap_axes_mm] + ["—"] * (3 - len(r.accuracy.ap_axes_mm))
        orientation = ()
        if r.orientation_accuracy is not None:
            orientation = tuple(f"{ap:+.3f} / ±{rp:.3f}" for ap, rp in zip(r.orientation_accuracy.ap_deg,
                                                                          r.orientation_repeatability.rp_deg))
        rows.append((r.label, str(r.accuracy.n), ", ".join(f"{v:g}" for v in r.commanded_mm), _pm(r.ap_u), *axes,
                     _pm(r.rp_u), floor, *orientation))
    return header, tuple(rows)


def _results(report: RunReport) -> Section:
    header, rows = pose_rows(report)
    k = f"{report.coverage_factor:g}"
    blocks: list[Block] = [Table("results", header, rows, f"Results per pose (U: expanded uncertainty, k = {k}; "
                                                          f"AP axes signed, barycentre − command)")]
    if report.distances:
        blocks.append(Table("distance", ("Pair / conditions", "D_c (mm)", "D̄ (mm)", "AD_p (mm)", "RD (mm)",
                                         f"U(AD) (mm, k = {k})"),
                            tuple((d.label, _mm(d.result.commanded_distance_mm), _mm(d.result.mean_distance_mm),
                                   _mm(d.result.ad_mm), f"± {_mm(d.result.rd_mm)}",
                                   _mm(d.u_ad.expanded_uncertainty)) for d in report.distances),
                            f"Distance accuracy and repeatability ({report.distances[0].first} ↔ "
                            f"{report.distances[0].second})"))
    if report.multidirectional:
        blocks.append(Table("vap", ("Pose", "Directions", "vAP_p (mm)"), tuple(
            (v.label, ", ".join(v.directions), _mm(v.result.vap_mm)) for v in report.multidirectional),
                            "Multi-directional pose accuracy variation"))
    if report.payload:
        rows = []
        for p in report.payload:
            for load, shift, norm in zip(p.result.load_kg, p.result.shift_mm, p.result.shift_norm_mm):
                rows.append((p.label, f"{load:g}", ", ".join(_mm(v) for v in shift), _mm(norm)))
        blocks.append(Table("payload", ("Pose", "Load (kg)", "PE(m) x, y, z (mm)", "|PE(m)| (mm)"), tuple(rows),
                            f"Payload error (project definition, reference load "
                            f"{report.payload[0].result.reference_load_kg:g} kg; not an ISO 9283 term)"))
    return Section("6. Results", tuple(blocks))


def _decision(report: RunReport) -> Section:
    blocks: list[Block] = [Paragraph(f"Decision rule: {report.decision.rule}.")]
    if report.decision.verdicts:
        blocks.append(Table("decision", ("Project criterion", "Pose", "Value (mm)", "Limit (mm)", "Result"),
                            tuple((f"{name} (project criterion)", label, _mm(value), _mm(limit),
                                   "pass" if ok else "fail") for name, label, value, limit, ok in
                                  report.decision.verdicts)))
    return Section("8. Decision", tuple(blocks))


def _raw(raw: list[RawData], notes: tuple[str, ...], recompute: str) -> Section:
    rows = tuple((r.name, r.sha256, str(r.rows)) for r in raw)
    blocks: list[Block] = [Paragraph(f"Every number above can be recomputed from these files: {recompute}."),
                           Table("rawdata", ("File", "SHA-256", "Rows"), rows, "Raw data")]
    excluded = notes or ("no sample excluded",)
    blocks.append(Paragraph("Excluded or incomplete data: " + "; ".join(excluded) + "."))
    return Section("9. Raw data", tuple(blocks))


def recompute_command(report: RunReport) -> str:
    """The CLI call that recomputes the per-pose results from the raw-data CSV."""
    sigma = report.instrument.sigma_mm or 0.0
    return f"bench analyze iso9283 FILE.csv --instrument-u-mm {sigma:.6g} --k {report.coverage_factor:g}"


def run_document(report: RunReport, raw: list[RawData], *, operator: str = "not recorded",
                 laboratory: str = "not recorded") -> Document:
    """The document of one run's report."""
    figures = tuple(Figure(p) for p in report_plots(report))
    return Document(
        title=f"{report.title}: run {report.run.id}", subtitle=f"Report {report.report_id}",
        sections=(_identification(report, operator, laboratory), _device(report), _method(report),
                  _conditions(report), _instruments(report), _results(report), Section("7. Plots", figures),
                  _decision(report), _raw(raw, report.notes, recompute_command(report)), Section("10. Statement of scope",
                                                                      (Paragraph(SCOPE),))),
        meta={"report_id": report.report_id})


def comparison_document(first: RunReport, second: RunReport, raw: list[RawData]) -> Document:
    """Two runs side by side: identification, differing conditions, deviations, paired results, plot."""
    a, b = first.run, second.run
    ident = [("Report ID", first.report_id, second.report_id), ("Protocol", a.protocol_name, b.protocol_name),
             ("Robot", a.robot, b.robot), ("Status", a.status, b.status),
             ("Started (UTC)", a.started_utc, b.started_utc), ("Git SHA", a.git_sha, b.git_sha),
             ("Configuration SHA-256", first.config_sha256[:16], second.config_sha256[:16]),
             ("Calibration ids", str(list(a.calibration_ids)), str(list(b.calibration_ids)))]
    keys = sorted(set(a.config) | set(b.config))
    differ = tuple((k, str(a.config.get(k)), str(b.config.get(k))) for k in keys if a.config.get(k) != b.config.get(k))
    deviations = tuple((d.clause, d.topic, f"{d.status}: {d.done}", f"{e.status}: {e.done}")
                       for d, e in zip(first.deviations, second.deviations))
    second_poses = {r.label: r for r in second.poses}
    paired = []
    for r in first.poses:
        s = second_poses.get(r.label)
        if s is None:
            continue
        paired.append((r.label, _pm(r.ap_u), _pm(s.ap_u), f"{s.accuracy.ap_mm - r.accuracy.ap_mm:+.4f}",
                       _pm(r.rp_u), _pm(s.rp_u), f"{s.repeatability.rp_mm - r.repeatability.rp_mm:+.4f}"))
    runs = f"run {a.id} (A) and run {b.id} (B)"
    return Document(
        title=f"Comparison of {runs}", subtitle=f"Reports {first.report_id} / {second.report_id}",
        sections=(
            Section("1. Identification", (Table("identification", ("Item", f"A: run {a.id}", f"B: run {b.id}"),
                                                tuple(ident)),)),
            Section("2. Conditions that differ", (Table("conditions", ("Parameter", "A", "B"), differ or (
                ("—", "identical configuration", ""),)),)),
            Section("3. Deviations from ISO 9283", (Paragraph(SCOPE), Table(
                "deviations", ("Clause", "Topic", "A", "B"), deviations)),),
            Section("4. Results", (Table("results", ("Pose", "AP_P ± U A (mm)", "AP_P ± U B (mm)", "ΔAP (B − A)",
                                                     "RP_l ± U A (mm)", "RP_l ± U B (mm)", "ΔRP (B − A)"),
                                         tuple(paired), f"Poses present in both runs, U with k = "
                                                        f"{first.coverage_factor:g}"),
                                   Figure(comparison_plot(first, second)))),
            _raw(raw, first.notes + second.notes, "see each run's own report")),
        meta={"report_id": f"{first.report_id}_vs_{second.report_id}"})
