"""The kinematic-calibration page of a comparison: two validation runs that differ by the calibration in force.

``bench report AFTER --compare BEFORE`` (either order) adds this page when the two pose runs commanded by different
kinematic calibrations (``settings.kinematic_calibration.id``, recorded by :mod:`bench.calibration.compensate`):
the run without one (or with the older one) is *before*, the other *after*. The page shows

* the gain (laser-grid runs with partial readings: :mod:`bench.reports.calibration_partial`): over the poses
  present in both runs, mean and largest AP_P, mean |AP| per axis and mean RP_l, before
  and after, with the factor before / after (ISO 9283 7.2.1 and 7.2.2 figures, as ``bench analyze iso9283``
  computes them per pose from each run's raw data);
* every pose side by side (AP_P, the signed AP vector per axis, RP_l, each with its expanded uncertainty);
* the error vectors over the workspace, before and after, on one magnification;
* the calibration in force after: its identified parameters with standard uncertainties, the parameters held at
  their documented values, the strongest correlations, the fit (reduced chi^2, residual RMS) and the observability
  (condition number against the limit 100, O1, the weak combinations), all as ``bench calibrate`` stored them.

Formulas: mean AP_P = (1/n) sum_j AP_P,j; mean |AP_x| = (1/n) sum_j |x̄_j - x_cj| (likewise y, z); mean RP_l =
(1/n) sum_j RP_l,j; factor = before / after (above 1: the calibration reduced the error).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from matplotlib.figure import Figure as MplFigure

from bench.metrology.formatting import format_pair, format_value, pose_label
from bench.reports.content import RunReport, axes_statement
from bench.reports.document import Document, Figure, Paragraph, Section, Table, fmt_mm, fmt_pm
from bench.reports.plots import MIN_FONT_PT, Plot
from bench.reports.pose_plots import workspace_cloud_mm

__all__ = [
    "CalibrationComparison",
    "calibration_comparison",
    "calibration_section",
    "gain_rows",
    "kinematic_calibration_id",
    "with_calibration_page",
]

_CONDITION_LIMIT = 100.0  # bench.metrology.kinematic_calibration.CONDITION_LIMIT (not imported: scipy at import)
_SHOWN_CORRELATIONS = 5


def kinematic_calibration_id(report: RunReport) -> int | None:
    """The id of the kinematic calibration run ``report`` commanded by, None when none was in force (or recorded)."""
    return (report.run.settings.get("kinematic_calibration") or {}).get("id")


@dataclass(frozen=True)
class CalibrationComparison:
    """A before / after pair of pose runs and the calibration records each commanded by (None: none)."""

    before: Any  #: RunReport, or GridPositioningReport (laser-grid readings, bench.reports.calibration_partial)
    after: Any
    before_calibration: Any | None  # bench.store CalibrationRecord
    after_calibration: Any


def calibration_comparison(store: Any, first: Any, second: Any) -> CalibrationComparison | None:
    """The pair ordered before -> after when the runs commanded by different kinematic calibrations (the run
    without one, else the one with the older calibration, is *before*); None when the calibrations are the same."""
    ids = kinematic_calibration_id(first), kinematic_calibration_id(second)
    if ids[0] == ids[1]:
        return None
    after_first = ids[1] is None or (ids[0] is not None and ids[0] > ids[1])
    (before, before_id), (after, after_id) = (
        ((second, ids[1]), (first, ids[0])) if after_first else ((first, ids[0]), (second, ids[1]))
    )
    return CalibrationComparison(
        before,
        after,
        None if before_id is None else store.calibration_by_id(before_id),
        store.calibration_by_id(after_id),
    )


def _name(record: Any | None) -> str:
    return "no kinematic calibration" if record is None else f"{record.name} v{record.version} (id {record.id})"


def _paired(pair: CalibrationComparison):
    after = {r.label: r for r in pair.after.poses}
    return [(r, after[r.label]) for r in pair.before.poses if r.label in after]


def _factor(before: float, after: float) -> str:
    return f"{before / after:.1f}" if after > 0 else "—"


def gain_rows(pair: CalibrationComparison) -> tuple[tuple[str, str, str, str], ...]:
    """The gain table's rows: quantity, before (mm), after (mm), factor before / after (module docstring).

    Each value is printed to the decimal place of the expanded uncertainties of the pose results it comes from
    (:func:`bench.metrology.formatting.format_value`, U to two significant digits): a mean to that of the smallest U
    among the poses it averages, the largest AP_P to its own pose's. A mean gets no U of its own: the poses share
    the instrument's systematic errors, so their uncertainties do not average down by a factor this table could
    state. The factor is computed from the unrounded values."""
    paired = _paired(pair)
    ap = np.array([[b.accuracy.ap_mm, a.accuracy.ap_mm] for b, a in paired])
    ap_u = np.array([[b.ap_u.expanded_uncertainty, a.ap_u.expanded_uncertainty] for b, a in paired])
    axes = np.array([[b.accuracy.ap_axes_mm, a.accuracy.ap_axes_mm] for b, a in paired])  # (n, 2, measured)
    rp = np.array([[b.repeatability.rp_mm, a.repeatability.rp_mm] for b, a in paired])
    rp_u = np.array([[b.rp_u.expanded_uncertainty, a.rp_u.expanded_uncertainty] for b, a in paired])
    largest = ap.argmax(axis=0)
    rows = [("mean AP_P", ap.mean(axis=0), ap_u.min(axis=0)), ("largest AP_P", ap.max(axis=0), ap_u[largest, [0, 1]])]
    rows += [
        (f"mean |AP_{name}|", np.abs(axes[:, :, i]).mean(axis=0), ap_u.min(axis=0))
        for i, name in enumerate(_axes(pair))
    ]
    rows.append(("mean RP_l", rp.mean(axis=0), rp_u.min(axis=0)))
    rows = [(name, format_value(v[0], u[0]), format_value(v[1], u[1]), _factor(*v)) for name, v, u in rows]
    rows[-1:-1] = [
        (f"mean |AP_{name}|", "not measured", "not measured", "—") for name in "xyz" if name not in _axes(pair)
    ]
    return tuple(rows)


def _axes(pair: CalibrationComparison) -> tuple[str, ...]:
    """The position axes both runs measured (their instrument may read a subset: the camera's x, y)."""
    before, after = pair.before.poses, pair.after.poses
    if before and after and before[0].axis_names != after[0].axis_names:
        from bench.errors import ConfigError

        raise ConfigError(
            f"--compare: run {pair.before.run.id} measured {', '.join(before[0].axis_names)} and run "
            f"{pair.after.run.id} {', '.join(after[0].axis_names)}; compare runs of the same axes"
        )
    return before[0].axis_names if before else ("x", "y", "z")


def _pose_rows(pair: CalibrationComparison) -> tuple[tuple[str, ...], ...]:
    rows = []
    for b, a in _paired(pair):
        cells = [pose_label(b.pose, b.conditions), fmt_pm(b.ap_u), fmt_pm(a.ap_u)]
        for name in "xyz":
            cells += [
                format_value(
                    dict(zip(r.axis_names, r.accuracy.ap_axes_mm))[name], r.ap_u.expanded_uncertainty, signed=True
                )
                if name in r.axis_names
                else "not measured"
                for r in (b, a)
            ]
        rows.append((*cells, fmt_pm(b.rp_u), fmt_pm(a.rp_u)))
    return tuple(rows)


def error_vectors(pair: CalibrationComparison) -> Plot | None:
    """The signed AP vector of every pose over the workspace (x-y and x-z), before (top) and after (bottom), on one
    magnification (set by the larger before); the x-y projection only for an instrument on the x-y plane (the
    camera), None for other subsets."""
    paired = _paired(pair)
    axes_measured = _axes(pair) if paired else ()
    projections = {("x", "y", "z"): ((0, 1), (0, 2)), ("x", "y"): ((0, 1),)}.get(axes_measured)
    if projections is None:
        return None
    commands = np.array([b.commanded_mm for b, _ in paired])
    vectors = [np.zeros((len(paired), 3)) for _ in range(2)]
    for vector, rows in zip(vectors, zip(*paired)):
        vector[:, : len(axes_measured)] = [r.accuracy.ap_axes_mm for r in rows]  # z stays 0: only x-y is drawn
    cloud = workspace_cloud_mm(pair.after.run.robot)
    points = commands if cloud is None else cloud
    scale = 0.15 * float(np.ptp(points, axis=0).max()) / max(float(np.abs(vectors[0]).max()), 1e-9)
    figure = MplFigure(figsize=(10 if len(projections) == 2 else 5.5, 8.4), layout="constrained")
    grid = figure.subplots(2, len(projections), squeeze=False)
    for row, (label, run, vector, colour) in enumerate(
        (("before", pair.before, vectors[0], "tab:red"), ("after", pair.after, vectors[1], "tab:blue"))
    ):
        for column, (i, j) in enumerate(projections):
            axes = grid[row][column]
            if cloud is not None:
                axes.scatter(
                    cloud[:, i], cloud[:, j], s=1, color="0.85", rasterized=True, label="reachable (kinematic model)"
                )
            axes.scatter(commands[:, i], commands[:, j], s=8, color="black", label="command poses")
            axes.quiver(
                commands[:, i],
                commands[:, j],
                vector[:, i] * scale,
                vector[:, j] * scale,
                color=colour,
                angles="xy",
                scale_units="xy",
                scale=1,
                width=0.005,
                zorder=3,
                label=f"AP vector x{scale:.0f}",
            )
            axes.set_xlabel(f"{'xyz'[i]} (mm)")
            axes.set_ylabel(f"{'xyz'[j]} (mm)")
            axes.set_title(f"{label}: run {run.run.id}", fontsize=MIN_FONT_PT + 1)
            axes.set_aspect("equal", adjustable="datalim")
            axes.legend(fontsize=MIN_FONT_PT, loc="lower left")
    views = "x-y and x-z projections" if len(projections) == 2 else "x-y projection; z not measured"
    return Plot(
        f"Error vectors over the workspace of the {pair.after.run.robot} ({views}): the "
        f"signed AP vector of every pose, before (run {pair.before.run.id}, {_name(pair.before_calibration)}) "
        f"and after (run {pair.after.run.id}, {_name(pair.after_calibration)}), both magnified {scale:.0f} "
        f"times.",
        figure,
    )


def _model_parameters(params: dict) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
    """(REGISTRATION, PARAMETERS) of the calibration model of the stored calibration's robot, None for another."""
    import importlib

    if params.get("robot") not in ("pkm5", "delta4"):
        return None
    model = importlib.import_module(f"motion.{params['robot']}.calibration")
    return model.REGISTRATION, model.PARAMETERS


def _model_order(params: dict) -> list[str]:
    """The identified parameter names in the model's order (registration first), as stored for other robots."""
    names = list(params.get("parameters", {}))
    model = _model_parameters(params)
    if model is None:
        return names
    order = {name: i for i, name in enumerate(model[0] + model[1])}
    return sorted(names, key=lambda name: order.get(name, len(order)))


def _parameter_rows(params: dict) -> tuple[tuple[str, str, str, str], ...]:
    rows = []
    for name in _model_order(params):
        entry = params["parameters"][name]
        value, u = format_pair(entry["value"], entry["uncertainty"], signed=True)
        rows.append((name, value, u, entry.get("unit", "")))
    return tuple(rows)


def _held(params: dict) -> tuple[str, ...]:
    """The model's parameters the calibration did not free (held at their documented values)."""
    model = _model_parameters(params)
    if model is None:
        return ()
    return tuple(name for name in model[1] if name not in params.get("parameters", {}))


def _correlations(params: dict) -> tuple[tuple[str, str, str], ...]:
    """The strongest correlations; the matrix is in the order of the fit's free parameters (the observability's
    names: the store keeps the parameter mapping sorted by name)."""
    names = list((params.get("observability") or {}).get("names") or ())
    matrix = np.asarray(params.get("correlation") or np.eye(len(names)), dtype=float)
    if matrix.shape != (len(names), len(names)) or len(names) < 2:
        return ()
    i, j = np.triu_indices(len(names), 1)
    order = np.argsort(-np.abs(matrix[i, j]))[:_SHOWN_CORRELATIONS]
    return tuple((names[i[k]], names[j[k]], f"{matrix[i[k], j[k]]:+.3f}") for k in order)


def _campaign_rows(params: dict, obs: dict) -> list[tuple[str, str]]:
    """The measurements and their two uncertainties, kept apart: the instrument's stated figure and the robot's
    measured scatter (a calibration stored before the per-pose means: every reading fitted alone)."""
    instrument = (
        "Instrument standard uncertainty (mm per axis, stated)",
        f"{params.get('uncertainty_mm', float('nan')):g}",
    )
    campaign = params.get("campaign")
    if not campaign:
        return [("Pose measurements (poses x cycles)", str(obs.get("n_poses", "—"))), instrument]
    cycles = campaign["cycles_per_pose"]
    scatter = campaign["scatter_mm"]
    rows = [
        ("Poses (each fitted by its mean)", str(len(cycles))),
        ("Cycles per pose", f"{min(cycles)}" if min(cycles) == max(cycles) else f"{min(cycles)}-{max(cycles)}"),
        instrument,
        (
            "Robot scatter of one reading (mm per axis, measured)",
            "not measured (one cycle)"
            if scatter[0] is None
            else f"{' / '.join(fmt_mm(v) for v in scatter)} ({campaign['scatter_dof']} degrees of freedom)",
        ),
        (
            "Standard uncertainty of a pose mean (mm per axis, RMS)",
            " / ".join(fmt_mm(v) for v in campaign["mean_uncertainty_mm"]),
        ),
    ]
    plan = campaign.get("plan")
    if plan and plan.get("calibration_cycles"):
        rows.append(
            (
                f"Plan for a {plan['target_gain']:g}x gain (cycles per pose: calibration / validation)",
                f"{plan['calibration_cycles']} / {plan.get('validation_cycles') or '—'}",
            )
        )
    return rows


def _fit_rows(record: Any) -> tuple[tuple[str, str], ...]:
    params = record.params
    obs = params.get("observability", {})
    singular = obs.get("singular_values") or [float("nan")]
    condition = float(obs.get("condition_number", float("nan")))
    verdict = "accepted" if condition <= _CONDITION_LIMIT else "above the limit"
    rows = [
        ("Source run", str(record.source_run_id)),
        ("Stored (UTC)", record.created_utc),
        ("Robot serial", str(params.get("dut_serial") or "none stated (the calibration run recorded no robot serial)")),
        *_campaign_rows(params, obs),
        ("Free parameters", str(len(params.get("parameters", {})))),
    ]
    is_map = params.get("fit") == "map"
    if is_map:  # a prior holds what the data cannot (docs/calibration.md, the refusal rule)
        rows += [
            ("Fit", f"maximum a posteriori, prior: {(params.get('prior') or {}).get('name', 'tolerances')}"),
            ("Fixed by the prior (the data did not inform them)", ", ".join(params.get("prior_only", ())) or "none"),
            ("Condition number of the data part", f"{condition:.3g} (the prior holds the weak directions)"),
        ]
    else:
        rows.append(("Condition number (limit 100)", f"{condition:.1f} ({verdict})"))
    weak = "Combinations the data alone cannot identify" if is_map else "Unidentifiable combinations"
    dof = params.get("degrees_of_freedom")  # absent from a MAP fit stored before 2026-12-03: chi^2 per coordinate
    chi2 = "Chi^2 per coordinate of the fit" if is_map and dof is None else "Reduced chi^2 of the fit"
    over = "" if dof is None or not is_map else f" over {float(dof):.1f} degrees of freedom"
    rows += [
        # dimensionless diagnostics of the fit, not measured figures: three significant digits say all they can
        ("O1 index (Borm & Menq)", f"{float(obs.get('o1', float('nan'))):.3g}"),
        ("Singular values, largest / smallest", f"{max(singular):.3g} / {min(singular):.3g}"),
        (weak, "; ".join(obs.get("unidentifiable", ())) or "none"),
        (chi2, f"{float(params.get('reduced_chi2', float('nan'))):.2f}{over}"),
        (
            "Residual RMS per coordinate before / after (mm)",
            f"{fmt_mm(params.get('residual_rms_before', float('nan')))} / "
            f"{fmt_mm(params.get('residual_rms', float('nan')))}",
        ),
    ]
    if "ap_before_mm" in params:
        rows.append(
            (
                "Mean position error on the calibration poses, before / after (mm, in-sample)",
                f"{fmt_mm(params['ap_before_mm'])} / {fmt_mm(params['ap_after_mm'])}",
            )
        )
    return tuple(rows)


def _pose_run_blocks(pair: CalibrationComparison) -> list:
    """The gain, the per-pose table and the error vectors of two pose runs (complete readings)."""
    before, after, record = pair.before, pair.after, pair.after_calibration
    rows = gain_rows(pair)
    k = f"{before.coverage_factor:g}"
    axes = axes_statement(after)
    blocks: list = [
        Paragraph(
            f"Before: run {before.run.id}, {_name(pair.before_calibration)} in force. After: run {after.run.id}, "
            f"{_name(record)} in force (identified from run {record.source_run_id}). Over the {len(_paired(pair))} "
            f"poses present in both runs the mean AP_P goes from {rows[0][1]} mm to {rows[0][2]} mm: "
            f"{rows[0][3]} times smaller." + (f" {axes}." if axes else "")
        ),
        Table(
            "calibration-gain",
            ("Quantity (over the poses of both runs)", "Before (mm)", "After (mm)", "Factor before / after"),
            rows,
            f"Gain of the calibration: run {before.run.id} (before) against run {after.run.id} (after); each "
            "value to the decimal place of the U of the pose results it comes from (a mean: the smallest U among "
            "them; a mean has no U of its own, as the poses share the instrument's systematic errors)"
            + (f"; {axes}" if axes else ""),
        ),
        Table(
            "calibration-poses",
            (
                "Pose",
                "AP_P ± U before (mm)",
                "AP_P ± U after (mm)",
                "AP_x before",
                "AP_x after",
                "AP_y before",
                "AP_y after",
                "AP_z before",
                "AP_z after",
                "RP_l ± U before (mm)",
                "RP_l ± U after (mm)",
            ),
            _pose_rows(pair),
            f"Per pose and axis, before and after (AP axes signed, barycentre − command, mm; U with k = {k}"
            + (f"; {axes}" if axes else "")
            + ")",
        ),
    ]
    plot = error_vectors(pair)
    if plot is not None:
        blocks.append(Figure(plot))
    return blocks


def calibration_section(pair: CalibrationComparison, number: int) -> Section:
    """The calibration page (module docstring) as section ``number`` of a comparison: the gain (pose runs, or
    laser-grid runs with partial readings: :func:`bench.reports.calibration_partial.partial_blocks`), then the
    calibration in force after."""
    from bench.reports.calibration_partial import partial_blocks

    record = pair.after_calibration
    blocks = _pose_run_blocks(pair) if isinstance(pair.after, RunReport) else partial_blocks(pair, _name)
    params = record.params
    blocks.append(
        Table(
            "calibration-parameters",
            ("Parameter", "Deviation from documented", "Standard uncertainty", "Unit"),
            _parameter_rows(params),
            f"Identified parameters of {_name(record)} (deviations from the documented geometry; "
            f"standard uncertainties, k = 1)",
        )
    )
    held = _held(params)
    blocks.append(
        Paragraph(
            "Held at their documented values (not identifiable from this pose set and "
            "instrument, or not freed): " + (", ".join(held) if held else "none") + "."
        )
    )
    correlations = _correlations(params)
    if correlations:
        blocks.append(
            Table(
                "calibration-correlations",
                ("Parameter", "Parameter", "Correlation"),
                correlations,
                f"The {len(correlations)} strongest correlations between identified parameters",
            )
        )
    blocks.append(
        Table(
            "calibration-observability",
            ("Item", "Value"),
            _fit_rows(record),
            "Fit and observability of the identification (SVD of the column-scaled, uncertainty-weighted Jacobian)",
        )
    )
    return Section(f"{number}. Kinematic calibration: before and after", tuple(blocks))


def with_calibration_page(document: Document, pair: CalibrationComparison | None) -> Document:
    """``document`` (a pose comparison) with the calibration page of ``pair`` (:func:`calibration_comparison`)
    before its raw-data section; ``document`` unchanged when ``pair`` is None (the same calibration in force)."""
    if pair is None:
        return document
    sections = list(document.sections)
    raw_at = next((i for i, s in enumerate(sections) if s.title.endswith("Raw data")), len(sections))
    numbers = [int(s.title.split(".")[0]) for s in sections[:raw_at] if s.title.split(".")[0].isdigit()]
    sections.insert(raw_at, calibration_section(pair, max(numbers, default=4) + 1))
    return replace(document, sections=tuple(sections))
