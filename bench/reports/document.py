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

from bench.metrology.formatting import format_length, format_measured, format_uncertainty
from bench.reports.blocks import Block, Document, Figure, Paragraph, RawData, Section, Table
from bench.reports.content import ReportBase
from bench.reports.instrument import ap_instrument_u_mm
from bench.reports.signature import PLACEHOLDER_SHOWN, is_placeholder
from bench.robot_kinds import ROBOT_KINDS
from bench.store.registrations import registration_u_mm, registrations

__all__ = [
    "Document",
    "Figure",
    "Paragraph",
    "RawData",
    "Section",
    "Table",
    "assemble",
    "conditions_section",
    "decision_blocks",
    "fmt_mm",
    "fmt_pm",
    "key_values",
    "reading_formatter",
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
    budget.extend(_registration_rows(report))
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


def _registration_rows(report: ReportBase) -> list[tuple[str, str, str]]:
    """A relative instrument's registration at home (measured in the run) and the term it makes with the reading
    in U of an accuracy (AP, AT_p): the number the raw-data line's --instrument-u-mm states; on a report that
    states such a U only (a stabilisation or positioning-time report states none)."""
    entries = registrations(report.run.settings)
    if not entries or not report.states_accuracy_u:
        return []
    total = ap_instrument_u_mm(report.instrument.sigma_mm, report.run)
    return [
        (
            "registration at home (the run's largest)",
            format_uncertainty(registration_u_mm(entries)),
            "measured in the run from the returns home (bench.rigs.registration); common to a segment's readings",
        ),
        (
            "accuracy term (AP, AT_p), per axis",
            format_uncertainty(total if total is not None else 0.0),
            "root sum of squares of the combined and the registration; the spread (RP, RT_p) excludes it",
        ),
    ]


def decision_blocks(rule: str, header: tuple[str, ...] = (), verdicts=()) -> tuple[Block, ...]:
    """The decision section's content: the rule, then one row per verdict when there are any."""
    blocks: list[Block] = [Paragraph(f"Decision rule: {rule}.")]
    if verdicts:
        blocks.append(Table("decision", header, tuple(verdicts)))
    return tuple(blocks)


def _raw(raw: list[RawData], notes: tuple[str, ...], recompute: str) -> Section:
    rows = tuple((r.name, r.sha256, str(r.rows)) for r in raw)
    blocks: list[Block] = [
        Paragraph(f"Every number above can be recomputed from these files: {recompute}.", verbatim=True),
        Table("rawdata", ("File", "SHA-256", "Rows"), rows, "Raw data"),
    ]
    excluded = notes or ("no sample excluded",)
    blocks.append(Paragraph("Excluded or incomplete data: " + "; ".join(excluded) + "."))
    return Section("9. Raw data", tuple(blocks))


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
