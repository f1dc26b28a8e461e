"""The pose run's figures: per-pose scatter, AP on the workspace, drift, deviation histograms, the 3-D error map,
PE(m) against load, the mouse calibration fit, and two runs' AP/RP side by side; drawn with the shared helpers of
:mod:`bench.reports.plots`."""

from __future__ import annotations

import logging

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from bench.reports.content import RunReport
from bench.reports.plots import (
    _POSITION,
    MIN_FONT_PT,
    PRINT_WIDTH_IN,
    Plot,
    nonnegative_yerr,
    payload_caption,
    payload_shift_figure,
    print_grid,
)
from bench.reports.small_multiples import legend_entries

_log = logging.getLogger(__name__)

__all__ = [
    "ap_on_workspace",
    "comparison_plot",
    "deviation_histograms",
    "drift_series",
    "error_map_3d",
    "hull_loop",
    "mouse_calibration_plots",
    "payload_plot",
    "pose_scatter",
    "report_plots",
    "workspace_cloud_mm",
]


def _rows_of(report: RunReport, result, columns: list[str]) -> np.ndarray:
    """The values of ``columns`` (rows, columns) of the samples of ``result`` (its pose and conditions), in cycle
    order; numpy masks on the table's columns (pandas' boolean indexing cost a report 50 ms for 45 selections)."""
    table = report.table
    mask = table["pose"].to_numpy() == result.pose
    for name, value in result.conditions:
        mask &= table[name].to_numpy() == value
    order = np.argsort(table["cycle"].to_numpy()[mask], kind="stable")
    return np.column_stack([table[column].to_numpy()[mask][order] for column in columns])


def _short_label(result) -> str:
    """``P1`` or ``P1, 100 %`` (panel titles: the conditions in short words)."""
    from bench.metrology.formatting import pose_label

    return pose_label(result.pose, result.conditions).replace(" velocity", "").replace(" load", "")


def _measured(result) -> tuple[np.ndarray, list[str]]:
    """The command on the measured axes and their columns (an instrument may read a subset, e.g. x, y)."""
    columns = [f"{a}_mm" for a in result.axis_names]
    return np.asarray(result.commanded_mm)[["xyz".index(a) for a in result.axis_names]], columns


def pose_scatter(report: RunReport) -> Plot:
    """Per pose: attained points minus the command (x-y plane), barycentre and the RP circle around it; one scale
    for every panel (the largest RP circle fits), one legend for the figure."""
    grid = print_grid(len(report.poses), (1.45, 1.45), equal_aspect=True)
    reach = max(
        float(np.abs(np.asarray(r.accuracy.ap_axes_mm[:2])).max()) + r.repeatability.rp_mm for r in report.poses
    )
    for result, panel in zip(report.poses, grid.panels):
        points = _rows_of(report, result, _POSITION[:2]) - np.asarray(result.commanded_mm[:2])
        centre = np.asarray(result.accuracy.ap_axes_mm[:2])
        panel.scatter(points[:, 0], points[:, 1], s=3, color="tab:blue", label="attained", linewidths=0)
        panel.plot(*centre, marker="+", color="tab:red", markersize=7, linestyle="", label="barycentre")
        panel.plot(0, 0, marker="x", color="black", linestyle="", label="command")
        panel.circle(
            centre, result.repeatability.rp_mm, fill=False, color="tab:red", lw=0.8, label="circle of radius RP_l"
        )
        panel.set_title(_short_label(result))
    grid.xlim = grid.ylim = (-reach * 1.05, reach * 1.05)  # square panels, one scale: circles are round
    figure = grid.finish("x − x_c (mm)", "y − y_c (mm)")
    return Plot(
        "Attained positions per pose relative to the command (x-y projection), with the barycentre "
        "and a circle of radius RP_l around it; every panel on the same scale.",
        figure,
    )


def workspace_cloud_mm(robot: str, count: int = 2500) -> np.ndarray | None:
    """Reachable positions (count, 3) of the robot's workspace from motion/ (seeded), or None when unknown."""
    try:
        if robot == "pkm5":
            from motion.pkm5 import sample_reachable

            return sample_reachable(count, seed=0)[:, :3]
        from motion.model import robot_models

        poses, reachable = robot_models()[robot].workspace_samples(5 * count, seed=0)
        return np.asarray(poses)[np.asarray(reachable), :3][:count]
    except Exception as exc:  # noqa: BLE001 - the plot is optional; the report says why it is missing
        _log.warning("workspace of %s not available for the report: %s", robot, exc)
        return None


def hull_loop(points: np.ndarray) -> np.ndarray | None:
    """Indices of the convex hull's vertices of the 2-D ``points`` (N, 2), counter-clockwise and closed (the first
    repeated last), or None when the points span no area. Andrew's monotone chain (Andrew 1979), here rather than
    scipy.spatial.ConvexHull: importing scipy.spatial costs a report process 0.3 s for one outline per figure."""
    points = np.asarray(points, dtype=float)
    order = np.lexsort((points[:, 1], points[:, 0])).tolist()
    xy = points.tolist()  # Python floats: the loop below indexes one point at a time

    def chain(indices) -> list[int]:
        kept: list[int] = []
        for index in indices:
            while len(kept) >= 2:
                (ax, ay), (bx, by) = xy[kept[-2]], xy[kept[-1]]
                cx, cy = xy[index]
                if (bx - ax) * (cy - ay) - (by - ay) * (cx - ax) > 0:  # a left turn: b stays on the hull
                    break
                kept.pop()
            kept.append(index)
        return kept

    lower, upper = chain(order), chain(order[::-1])
    loop = lower[:-1] + upper[:-1]
    if len(loop) < 3:
        return None
    return np.array([*loop, loop[0]])


def ap_on_workspace(report: RunReport) -> Plot | None:
    """Workspace cloud and hull (x-y and x-z projections) with each pose's AP vector, magnified."""
    cloud = workspace_cloud_mm(report.run.robot)
    commands = np.array([r.commanded_mm for r in report.poses])
    vectors = np.array([r.accuracy.ap_axes_mm for r in report.poses])
    if cloud is None or vectors.shape[1] < 3:
        return None
    span = float(np.ptp(cloud, axis=0).max())
    scale = 0.15 * span / max(float(np.abs(vectors).max()), 1e-9)
    # a fixed layout (margins for the axis labels, the one legend on top) and the legend placed, not searched for:
    # constrained layout and loc="best" over 2,500 points each measured the figure once more (half of its time)
    width, height = PRINT_WIDTH_IN, 3.2
    figure = Figure(figsize=(width, height))
    figure.subplots_adjust(
        left=0.62 / width, right=1 - 0.06 / width, bottom=0.48 / height, top=1 - 0.32 / height, wspace=0.22
    )
    for index, (i, j) in enumerate(((0, 1), (0, 2))):
        axes = figure.add_subplot(1, 2, index + 1)
        axes.scatter(cloud[:, i], cloud[:, j], s=1, color="0.8", label="reachable (kinematic model)", rasterized=True)
        loop = hull_loop(cloud[:, [i, j]])
        if loop is not None:
            axes.plot(cloud[loop, i], cloud[loop, j], color="0.4", lw=1, label="hull")
        axes.quiver(
            commands[:, i],
            commands[:, j],
            vectors[:, i] * scale,
            vectors[:, j] * scale,
            color="tab:red",
            angles="xy",
            scale_units="xy",
            scale=1,
            width=0.004,
            label=f"AP vector x{scale:.0f}",
        )
        axes.scatter(commands[:, i], commands[:, j], s=12, color="black", label="command poses")
        names = "xyz"
        axes.set_xlabel(f"{names[i]} (mm)")
        axes.set_ylabel(f"{names[j]} (mm)")
        axes.set_aspect("equal", adjustable="datalim")
    legend = legend_entries(figure.axes)
    figure.legend(list(legend.values()), list(legend), loc="upper center", ncols=len(legend), fontsize=MIN_FONT_PT)
    return Plot(
        f"Workspace of the {report.run.robot} (reachable points and convex hull, projections) with the "
        f"signed AP vector of every pose magnified {scale:.0f} times.",
        figure,
    )


def drift_series(report: RunReport) -> Plot:
    """Small multiples, one panel per pose, on one scale: per-cycle distance of each attained point from its
    command in cycle order (drift and warm-up), one line per set of conditions, one legend for the figure."""
    from bench.metrology.formatting import condition_text

    names = list(dict.fromkeys(r.pose for r in report.poses))
    grid = print_grid(len(names), (1.45, 1.5))
    by_pose = dict(zip(names, grid.panels))
    for result in report.poses:
        command, measured = _measured(result)
        rows = _rows_of(report, result, ["cycle", *measured])
        distance = np.linalg.norm(rows[:, 1:] - command, axis=1)
        by_pose[result.pose].plot(
            rows[:, 0],
            distance,
            marker=".",
            markersize=2,
            lw=0.8,
            label=condition_text(result.conditions) or "all cycles",
        )
    for name, panel in by_pose.items():
        panel.set_title(name)
    grid.x_locator = MaxNLocator(integer=True, nbins=4)
    figure = grid.finish("cycle", "|attained − command| (mm)")
    return Plot(
        "Per pose, on one scale: distance of each attained point from its command, cycle by cycle (a trend "
        "shows drift or warm-up).",
        figure,
    )


def deviation_histograms(report: RunReport) -> Plot:
    """Small multiples, one panel per pose (and condition), on one scale and one set of bins: histograms of the
    attained − command deviation in x, y and z, one legend for the figure."""
    deviations = []
    for result in report.poses:
        command, columns = _measured(result)
        deviations.append(_rows_of(report, result, columns) - command)
    edges = np.histogram_bin_edges(np.concatenate(deviations).ravel(), bins=24)
    grid = print_grid(len(report.poses), (1.45, 1.2))
    for result, panel, deviation in zip(report.poses, grid.panels, deviations):
        for column, (name, colour) in enumerate(zip(result.axis_names, ("tab:blue", "tab:orange", "tab:green"))):
            panel.step_histogram(deviation[:, column], edges, color=colour, lw=1.0, label=f"{name} − {name}_c")
        panel.vline(0.0, color="0.4", lw=0.6)
        panel.set_title(_short_label(result))
    grid.y_locator = MaxNLocator(integer=True, nbins=4)
    figure = grid.finish("attained − command (mm)", "cycles")
    return Plot(
        "Per pose, on one scale and with the same bins: histograms of the deviation of every attained "
        "position from its command, per axis (the offset of a histogram from 0 is the signed AP of that "
        "axis, its width the scatter behind RP).",
        figure,
    )


def error_map_3d(report: RunReport) -> Plot | None:
    """The test volume in 3-D: one signed AP vector per pose and set of conditions from its command pose, magnified
    by one common factor, its tip coloured by AP_P on one colour scale; None for planar instruments."""
    if not report.poses or len(report.poses[0].accuracy.ap_axes_mm) < 3:
        return None
    commands = np.array([r.commanded_mm for r in report.poses])
    vectors = np.array([r.accuracy.ap_axes_mm for r in report.poses])
    ap = np.array([r.accuracy.ap_mm for r in report.poses])
    span = max(float(np.ptp(commands, axis=0).max()), 1e-9)
    scale = 0.25 * span / max(float(np.abs(vectors).max()), 1e-9)
    figure = Figure(figsize=(6.0, 4.6))
    figure.subplots_adjust(left=0.0, right=0.86, bottom=0.04, top=0.98)
    axes = figure.add_subplot(1, 1, 1, projection="3d")
    tips = commands + vectors * scale
    axes.quiver(*commands.T, *(vectors * scale).T, color="0.35", lw=0.8, arrow_length_ratio=0.15)
    axes.scatter(*commands.T, color="black", marker="x", s=14, depthshade=False, label="command pose")
    points = axes.scatter(
        *tips.T, c=ap, cmap="viridis", vmin=0.0, s=16, depthshade=False, label=f"barycentre (AP vector x{scale:.0f})"
    )
    for pose, command in dict((r.pose, r.commanded_mm) for r in report.poses).items():
        axes.text(*command, f"  {pose}", fontsize=MIN_FONT_PT)
    for name, setter in zip("xyz", (axes.set_xlabel, axes.set_ylabel, axes.set_zlabel)):
        setter(f"{name} (mm)", fontsize=MIN_FONT_PT, labelpad=0)
    axes.tick_params(labelsize=MIN_FONT_PT, pad=0)
    axes.legend(loc="upper left", fontsize=MIN_FONT_PT, frameon=False)
    figure.colorbar(points, ax=axes, shrink=0.6, pad=0.08, label="AP_P (mm)")
    groups = len({r.conditions for r in report.poses})
    return Plot(
        f"Error map over the test volume: at every command pose (x) the signed AP vector to the barycentre, "
        f"magnified {scale:.0f} times, its tip coloured by AP_P (one colour scale)"
        + (f"; one vector per set of conditions ({groups})." if groups > 1 else "."),
        figure,
    )


def payload_plot(report: RunReport) -> Plot | None:
    """|PE(m)| and its z component (sag) against load, one line per pose."""
    if not report.payload:
        return None
    figure, axes = payload_shift_figure([(row.label, row.result) for row in report.payload])
    for each in axes:
        each.legend(fontsize=6)
    return Plot(payload_caption(report.payload[0].result.reference_load_kg), figure)


def mouse_calibration_plots(report: RunReport) -> list[Plot]:
    """Fit and residuals of every calibration in force whose source run holds its step data."""
    plots = []
    for item in report.instrument.fits:
        record, fit = item.record, item.fit
        reference = np.asarray(item.reference_mm, dtype=float)
        figure = Figure(figsize=(10, 3.4), layout="constrained")
        data, residual = figure.add_subplot(1, 2, 1), figure.add_subplot(1, 2, 2)
        data.scatter(reference, item.counts, s=10, label="calibration steps")
        data.plot(
            reference,
            fit.slope_counts_per_mm * reference + fit.offset_counts,
            color="tab:red",
            label=f"fit: {fit.scale_mm_per_count:.5f} mm/count",
        )
        data.set_xlabel(f"commanded {item.axis} step (mm)")
        data.set_ylabel("counts")
        data.legend(fontsize=7)
        residual.axhline(0.0, color="0.5", lw=1)
        residual.scatter(reference, fit.residuals_counts, s=10)
        residual.set_xlabel(f"commanded {item.axis} step (mm)")
        residual.set_ylabel("residual (counts)")
        plots.append(
            Plot(
                f"Calibration {record.name} v{record.version} (id {record.id}, from run "
                f"{record.source_run_id}), {item.axis} axis: linear fit and residuals, RMS "
                f"{fit.residual_rms_counts:.3g} counts.",
                figure,
            )
        )
    return plots


def report_plots(report: RunReport) -> list[Plot]:
    """Every figure of one run's report, in report order (optional ones left out when their data is absent)."""
    plots = [
        pose_scatter(report),
        deviation_histograms(report),
        error_map_3d(report),
        ap_on_workspace(report),
        drift_series(report),
        payload_plot(report),
        *mouse_calibration_plots(report),
    ]
    return [p for p in plots if p is not None]


def comparison_plot(first: RunReport, second: RunReport) -> Plot:
    """AP_P and RP_l per pose label for two runs, with the expanded uncertainties as error bars."""
    labels = list(dict.fromkeys([r.label for r in first.poses] + [r.label for r in second.poses]))
    figure = Figure(figsize=(10, 3.8), layout="constrained")
    positions = np.arange(len(labels))
    for index, (name, attribute) in enumerate((("AP_P", "ap_u"), ("RP_l", "rp_u"))):
        axes = figure.add_subplot(1, 2, index + 1)
        for offset, report in ((-0.2, first), (0.2, second)):
            by_label = {r.label: getattr(r, attribute) for r in report.poses}
            values = [by_label[label].value if label in by_label else np.nan for label in labels]
            errors = [by_label[label].expanded_uncertainty if label in by_label else 0.0 for label in labels]
            axes.bar(
                positions + offset,
                values,
                width=0.4,
                yerr=nonnegative_yerr(values, errors),
                capsize=2,
                label=f"run {report.run.id}",
            )
        axes.set_xticks(positions, labels, rotation=45, ha="right", fontsize=6)
        axes.set_ylabel(f"{name} (mm)")
        axes.legend(fontsize=7)
    return Plot(
        f"AP_P and RP_l per pose, run {first.run.id} against run {second.run.id} "
        f"(error bars: U, k = {first.coverage_factor:g}).",
        figure,
    )
