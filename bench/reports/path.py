"""The report of an ISO 9283 path run (``iso9283_path``, ``iso9283_cornering``): AT/RT (8.2, 8.3), CR/CO (8.5) and
AV/RV/FV (8.6) from the run's raw streamed samples, with its deviations table and a figure of the commanded and the
attained paths in the test plane.

Every figure comes from :func:`bench.reports.path_run.analyze_path_run`, the computation ``bench analyze path-run``
prints; the raw-data CSV is the streamed series (``bench export RUN --kind path --series``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from bench.metrology import Measured
from bench.metrology.formatting import format_length
from bench.metrology.uncertainty_figures import PATH_U_MIN_CYCLES
from bench.reports.content import ReportBase, calibrations_in_force, provenance
from bench.reports.criteria import Characteristic, decision_section
from bench.reports.deviations import Deviation, _fmt, _planned_count, _row
from bench.reports.document import Paragraph, RawData, Table, assemble, conditions_section
from bench.reports.instrument import counts_instrument
from bench.reports.path_run import PLOTTED_CYCLES, PathRun, analyze_path_run, figure_text
from bench.reports.plots import MIN_FONT_PT, Plot, print_grid
from bench.reports.rawdata import StreamedSeries
from bench.store import Store

__all__ = ["PathReport", "collect_path", "path_deviations", "path_document", "path_plot"]

SCOPE = (
    "Tested following the methods of ISO 9283:1998 clause 8 (path characteristics), with the deviations listed "
    "in the deviations table. Results are ISO 9283-style; this is not an ISO 9283 certification."
)
NO_CRITERION = "no acceptance criterion stated: no pass/fail statement (ISO 9283 defines methods, not grades)"
#: ISO 9283 Table 5 [N]: cycles of the path tests.
PATH_CYCLES, CORNERING_CYCLES = 10, 3


@dataclass(frozen=True, kw_only=True)
class PathReport(ReportBase):
    """Everything the report of a path run prints."""

    states_accuracy_u: ClassVar[bool] = True  # U(AT_p)
    analysis: PathRun
    store_path: str


#: ISO 9283 8.4 (path accuracy on reorientation) is not offered on this bench, and why (docs/metrology.md).
REORIENTATION_NOT_MEASURED = (
    "path accuracy on reorientation (ISO 9283 8.4) not measured: it needs the orientation sampled along the moving "
    "path, and the instruments stream position only (the mice); the orientation is read by calliper at stops"
)


def path_deviations(run, analysis: PathRun) -> list[Deviation]:
    """Departures of a path run from ISO 9283 clause 8 (iso9283.md §6.10-6.14): cycles, velocities, the paths, the
    joint-space segmentation, the velocity reference and the instrument."""
    config, protocol = run.config, analysis.design
    cornering = run.protocol_name == "iso9283_cornering"
    required = CORNERING_CYCLES if cornering else PATH_CYCLES
    measured = min(f.n_cycles for f in analysis.figures)
    rows = [
        _planned_count(
            "ISO 9283 6.9",
            "cycles",
            f"{required} cycles (Table 5)",
            config,
            "cycles",
            measured=measured,
            required=required,
            counted="complete",
            where="any path and velocity",
            effect="RT and RV from fewer cycles than the standard's",
        )
    ]
    velocities = [float(v) for v in config.get("velocities_pct", ())]
    rows.append(
        _row(
            "ISO 9283 6.7",
            "velocity",
            "100, 50 and 10 % of the rated path velocity [U]",
            f"{_fmt(velocities)} % of {protocol.rated_mm_s:g} mm/s ("
            + (
                "stated"
                if config.get("path_speed_mm_s")
                else "the largest the legs hold on every segment at the firmware's rated step rate"
            )
            + ")",
            sorted(velocities) == [10.0, 50.0, 100.0] and bool(config.get("path_speed_mm_s")),
            "no rated path velocity is declared for this robot; the reference velocity is derived",
        )
    )
    shapes = ", ".join(protocol.shapes)
    rows.append(
        _row(
            "ISO 9283 6.8",
            "paths",
            "straight line, rectangle, large and small circle in the test plane [U]",
            f"{shapes} in the cube's {config.get('plane', 'x=z')} plane, cube edge "
            f"{config.get('cube_side_mm', 0):g} mm",
            False,
            "one circle (radius 0.4 L); the other paths in a run of the other path protocol",
        )
    )
    chord = max(protocol.max_chord_error_mm[s] for s in protocol.shapes)
    rows.append(
        _row(
            "ISO 9283 8.1",
            "interpolation",
            "continuous path control by the robot",
            f"host-side segments, joint-linear moves, chord error <= {protocol.chord_error_mm:g} mm "
            f"(largest {format_length(chord)} mm); the robot stops briefly at every segment end",
            False,
            "stops at the segment ends lower the mean path speed and raise FV; corners are approached "
            "from rest, so CO shows the structure's ringing rather than a controller's smoothing",
        )
    )
    rows.append(
        _row(
            "ISO 9283 8.2",
            "stations",
            "planes normal to the commanded path [U]",
            "every 1 mm, none within 5 mm of the path's start and end or 2 mm of the rectangle's corners",
            True,
            "",
        )
    )
    if "AV_pct" in {k for f in analysis.figures for k in f.as_json()}:
        rows.append(
            _row(
                "ISO 9283 8.6",
                "speed samples",
                "velocity over the constant-velocity part [U]",
                "position differences 2 mm of commanded travel apart, middle 80 % of the line's time",
                True,
                "",
            )
        )
    rows.append(
        _row(
            "ISO 9283 8.4",
            "reorientation",
            "straight line with prescribed orientation changes, AT_a/b/c and RT_a/b/c along it [U]",
            "not tested: constant orientation along every path",
            False,
            REORIENTATION_NOT_MEASURED,
        )
    )
    return rows


def collect_path(
    store: Store, run_id: int, *, k: float = 2.0, resamples: int = 1000, allow_unknown: bool = False
) -> PathReport:
    """Gather the facts and figures of the report of path run ``run_id`` (``k``, ``resamples`` unused: the path
    figures' U are for k = 2, as ``bench analyze path|path-velocity`` state them; ``allow_unknown`` unused: no row
    here can be unknown)."""
    run = store.run(run_id)
    raw = StreamedSeries(store, run_id, "path")  # the raw-data CSV, spooled as the analysis reads the run: once
    if hasattr(store, "iter_samples_text"):  # a sample at a time, its number text reused for the CSV
        samples = raw.passing_stored(store.iter_samples_text(run_id, kind="path"))
    else:  # a lab view: a list
        samples = raw.passing(store.samples(run_id, kind="path"))
    analysis = analyze_path_run(store, run_id, samples=samples)
    calibrations = calibrations_in_force(store, run)
    clauses = ("8.5 cornering deviations",) if run.protocol_name == "iso9283_cornering" else ()
    return PathReport(
        **provenance(run, calibrations),
        title=run.config.get("title") or "ISO 9283-style path characteristics",
        clauses=("8.2 path accuracy", "8.3 path repeatability", *clauses)
        + (("8.6 path velocity",) if "line" in analysis.design.shapes else ()),
        deviations=tuple(path_deviations(run, analysis)),
        instrument=analysis.instrument or counts_instrument(run, calibrations, 0),
        table=raw,  # never held: written where the report goes from the spool (or the open store)
        coverage_factor=k,
        analysis=analysis,
        store_path=store.path,
    )


def _cell(value, fmt: str) -> str:
    return "—" if value is None else format(value, fmt)


def _results(report: PathReport) -> tuple:
    rows, corners = [], []
    for f in report.analysis.figures:
        j = f.as_json()
        rows.append(
            (
                f.shape,
                f"{f.velocity_pct:g}",
                f"{f.commanded_mm_s:.3f}",
                str(f.n_cycles),
                figure_text(f.at_mm, f.at_u),
                figure_text(f.rt_mm, f.rt_u),
                _cell(j.get("CR_mm"), ".3f"),
                _cell(j.get("CO_mm"), ".3f"),
                figure_text(f.av_pct, f.av_u, signed=True),
                figure_text(f.rv_pct, f.rv_u),
                _cell(f.fv_mm_s, ".3f"),
            )
        )
        corners += [(f.shape, f"{f.velocity_pct:g}", c, f"{cr:.3f}", f"{co:.3f}") for c, cr, co in f.corners]
    blocks = [
        Table(
            "path",
            (
                "Path",
                "v (%)",
                "v_c (mm/s)",
                "Cycles",
                "AT ± U (mm)",
                "RT ± U (mm)",
                "CR (mm)",
                "CO (mm)",
                "AV ± U (%)",
                "RV ± U (%)",
                "FV (mm/s)",
            ),
            tuple(rows),
            "Path accuracy AT and repeatability RT (ISO 9283 8.2, 8.3) per path and velocity; cornering "
            "round-off CR and overshoot CO (8.5), worst corner; path velocity accuracy AV, repeatability RV and "
            "fluctuation FV (8.6) on the line",
        )
    ]
    if corners:
        blocks.append(
            Table(
                "corners",
                ("Path", "v (%)", "Corner", "CR (mm)", "CO (mm)"),
                tuple(corners),
                "Cornering deviations per corner, worst cycle (P2, where each cycle starts and ends at "
                "rest, is not a corner passed through)",
            )
        )
    blocks.append(Paragraph(uncertainty_statement(report.analysis)))
    return tuple(blocks)


def uncertainty_statement(analysis: PathRun) -> str:
    """What the U of the path table are and what their budgets hold, in the words ``bench analyze path`` and
    ``bench analyze path-velocity`` use; values rounded by their U."""
    few = sorted({f.n_cycles for f in analysis.figures if f.at_u is None})
    text = (
        f"U with k = 2, values rounded by their U: U(AT_p), U(RT_p) from a Monte Carlo of the path model "
        f"(docs/metrology.md); {analysis.budget}."
    )
    if few:
        text += (
            f" No U(AT_p), U(RT_p) where {' or '.join(map(str, few))} cycles were measured: the path model needs at "
            f"least {PATH_U_MIN_CYCLES}."
        )
    if any(f.av_u is not None for f in analysis.figures):
        text += (
            " U(AV): Student's k for the cycles' mean speeds (k at ν_eff, as bench analyze path-velocity prints "
            f"it); U(RV): the chi pivot of the spread; {analysis.speed_budget}."
        )
    return text + " CR, CO and FV carry no U; one instrument count sets the smallest figure the paths can show."


def path_plot(report: PathReport) -> Plot:
    """Per path: the commanded path and the attained cycles of the highest velocity, in the test plane (u along
    P2 -> P5, v along P2 -> P3, mm from P1), every panel on one scale; one legend for the figure."""
    protocol = report.analysis.design
    shapes = list(protocol.shapes)
    grid = print_grid(
        len(shapes), (3.4, 3.0), max_columns=2, equal_aspect=True
    )  # one scale for u and v: the paths' true shape
    for panel, shape in zip(grid.panels, shapes):
        path = protocol.path(shape)
        origin = path.centre_mm

        def plane(points):
            relative = np.asarray(points) - origin
            return relative @ path.u, relative @ path.v

        keys = sorted((k for k in report.analysis.cycles if k[0] == shape), key=lambda k: -k[1])
        for index, (_, points) in enumerate(report.analysis.cycles[keys[0]] if keys else []):
            u, v = plane(points)
            panel.plot(u, v, lw=0.7, color=f"C{index % 10}", label=f"attained, cycle {index + 1}")
        u, v = plane(path.point(np.linspace(0.0, path.length_mm, 400)))
        panel.plot(u, v, lw=1.2, color="black", ls="--", label="commanded")
        for label, corner in zip(("P3", "P4", "P5"), path.corners_mm[:3]):
            cu, cv = plane(corner[None, :])
            panel.annotate(label, (cu[0], cv[0]), fontsize=MIN_FONT_PT)
        panel.set_title(shape + (f" at {keys[0][1]:g} %" if keys else ""))
    half = 1.05 * max(
        max(
            np.linalg.norm(protocol.path(s).vertices_mm - protocol.path(s).centre_mm, axis=1),
            default=protocol.path(s).radius_mm,
        )
        for s in shapes
    )
    grid.xlim = grid.ylim = (-half, half)
    figure = grid.finish(
        "u: along P2 → P5, from P1 (mm)", "v: along P2 → P3, from P1 (mm)", legend_pt=MIN_FONT_PT, legend_columns=4
    )
    drawn = [
        max(keys, key=lambda k: k[1]) for s in shapes if (keys := [k for k in report.analysis.cycles if k[0] == s])
    ]
    held = max((report.analysis.cycle_counts.get(k, 0) for k in drawn), default=0)
    cycles = "every cycle" if held <= PLOTTED_CYCLES else f"the first {PLOTTED_CYCLES} of {held} cycles"
    return Plot(
        f"Commanded (dashed) and attained paths in the test plane at the highest velocity, {cycles}, all "
        "panels on one scale (the deviations are those of the robot: they are not magnified).",
        figure,
    )


def path_document(report: PathReport, raw: list[RawData], *, operator: str = "—", laboratory: str = "—"):
    protocol = report.analysis.design
    method = (
        "ISO 9283:1998 clause 8. The path is cut into straight segments whose joint-space chord error is at "
        f"most {protocol.chord_error_mm:g} mm; every segment end passes the pre-flight (reachable, within the "
        "joint limits, away from singularities). Each segment is one move at the leg speed giving the "
        "commanded path velocity, and the instrument's position is streamed over it. AT_p = max_i |p̄_i − "
        "p_ci| and RT_p = max_i (l̄_i + 3 S_li) over planes normal to the commanded path every 1 mm; CR = "
        "min_t |P_E − p(t)|, CO = the largest excursion beyond the outgoing side after the corner; AV = (v̄ − "
        "v_c)/v_c, RV = 3 S_v/v_c, FV = max_j (max_i v_ij − min_i v_ij) over the middle 80 % of the line."
    )
    extra = (
        ("rated path velocity (mm/s)", f"{protocol.rated_mm_s:g}"),
        ("segments", ", ".join(f"{s} {protocol.n_segments(s)}" for s in protocol.shapes)),
    )
    recompute = f"bench analyze path-run {report.run.id} --store {report.store_path} --json"
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
                "path_speed_mm_s",
                "cycles",
                "shape",
                "load_kg",
                "cube_centre_mm",
                "cube_side_mm",
                "plane",
                "chord_error_mm",
            ),
            extra,
        ),
        results=_results(report),
        plots=[path_plot(report)],
        decision=decision_section(report, NO_CRITERION),
        recompute=recompute,
    )


def _expanded(measured: Measured | None) -> float | None:
    return None if measured is None else measured.expanded_uncertainty


#: What ``--criterion`` judges in a path report: AT_p and RT_p of every path and velocity, RV on the line, each with
#: its U where the run has one (the guarded rule proves nothing without it).
CHARACTERISTICS = {
    "AT_mm": Characteristic(
        "path accuracy AT_p of every path and velocity",
        lambda report: [
            (f"{f.shape}, {f.velocity_pct:g} %", f.at_mm, _expanded(f.at_u)) for f in report.analysis.figures
        ],
    ),
    "RT_mm": Characteristic(
        "path repeatability RT_p of every path and velocity",
        lambda report: [
            (f"{f.shape}, {f.velocity_pct:g} %", f.rt_mm, _expanded(f.rt_u)) for f in report.analysis.figures
        ],
    ),
    "RV_pct": Characteristic(
        "path velocity repeatability RV of the line at every velocity",
        lambda report: [
            (f"{f.shape}, {f.velocity_pct:g} %", f.rv_pct, _expanded(f.rv_u))
            for f in report.analysis.figures
            if f.rv_pct is not None
        ],
    ),
}
