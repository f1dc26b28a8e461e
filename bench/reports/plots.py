"""The report's figures, drawn with matplotlib's object API (no pyplot state, Agg/SVG canvases only).

Every plotted quantity is either a raw stored sample or a number the metrology already computed for the report
(barycentres, RP, AP vectors, PE(m), calibration fits); nothing is re-derived here. A figure is returned as a
:class:`Plot` (caption plus a matplotlib ``Figure``); :func:`png_bytes` renders it once, at :data:`REPORT_DPI`, and
that one image serves the HTML (inline, as a data URI) and the PDF (reportlab embeds bitmaps without another
dependency): drawing a figure is most of a report's time, and a second, vector rendering for the HTML doubled it.
:func:`svg_text` stays for a vector copy of one figure (tests measure fonts in it).
"""

from __future__ import annotations

import io
import logging
import math
import os
import pickle
import threading
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from matplotlib.text import Text
from matplotlib.ticker import MaxNLocator

from bench.reports.content import RunReport
from bench.reports.png import rgb_png
from bench.reports.small_multiples import SmallMultiples, legend_entries

__all__ = [
    "MIN_FONT_PT",
    "PRINT_HEIGHT_IN",
    "PRINT_WIDTH_IN",
    "Plot",
    "REPORT_DPI",
    "comparison_plot",
    "deviation_histograms",
    "draw_all",
    "error_map_3d",
    "hull_loop",
    "legend_entries",
    "print_grid",
    "print_ready",
    "panels",
    "payload_caption",
    "payload_shift_figure",
    "png_bytes",
    "report_plots",
    "svg_text",
    "workspace_cloud_mm",
]

_log = logging.getLogger(__name__)
_POSITION = ["x_mm", "y_mm", "z_mm"]


#: Width of the text block of an A4 page with 15 mm margins (180 mm), inches: figures are drawn at this size so a
#: point in the figure is a point on paper; and the tallest figure a page holds (200 mm).
PRINT_WIDTH_IN = 180 / 25.4
PRINT_HEIGHT_IN = 200 / 25.4
#: Smallest font on paper (pt): tick labels, legends, annotations.
MIN_FONT_PT = 7.0


def print_ready(figure: Figure) -> Figure:
    """Make ``figure`` readable at print size, once: scaled to fit :data:`PRINT_WIDTH_IN` x :data:`PRINT_HEIGHT_IN`
    (keeping its aspect), every text at least :data:`MIN_FONT_PT`, then its layout computed once and frozen (a
    fixed layout: saving it as SVG and PNG draws it once each, with no layout pass per save)."""
    if getattr(figure, "_bench_print_ready", False):
        return figure
    width, height = figure.get_size_inches()
    scale = min(PRINT_WIDTH_IN / width, PRINT_HEIGHT_IN / height)
    figure.set_size_inches(width * scale, height * scale)
    for axes in figure.axes:
        axes.tick_params(labelsize=MIN_FONT_PT)
    for text in _texts(figure):
        if text.get_fontsize() < MIN_FONT_PT:
            text.set_fontsize(MIN_FONT_PT)
    engine = figure.get_layout_engine()
    if engine is not None:
        engine.execute(figure)
        figure.set_layout_engine("none")
    figure._bench_print_ready = True
    return figure


def _texts(figure: Figure):
    """Every text of ``figure`` but the tick labels (sized by ``tick_params``): a walk of what holds texts instead of
    ``findobj``, which builds every tick of every axis to visit it (a quarter of a small-multiples figure's time)."""
    legends = list(figure.legends)
    yield from figure.texts
    for axes in figure.axes:
        yield from (axes.title, axes._left_title, axes._right_title)
        yield from (a for a in axes.texts if isinstance(a, Text))
        for axis in axes._axis_map.values():
            yield from (axis.label, axis.offsetText)
        if axes.get_legend() is not None:
            legends.append(axes.get_legend())
        for child in axes.get_children():  # annotations, anchored texts and the like that are not in axes.texts
            if isinstance(child, Text) and child not in axes.texts:
                yield child
    for legend in legends:
        yield from (*legend.get_texts(), legend.get_title())


@dataclass(frozen=True)
class Plot:
    caption: str
    figure: Figure

    def __post_init__(self) -> None:
        print_ready(self.figure)


def svg_text(plot: Plot) -> str:
    """The figure as an inline ``<svg>`` element (XML prolog and DOCTYPE stripped)."""
    buffer = io.StringIO()
    plot.figure.savefig(buffer, format="svg", metadata={"Date": None})
    text = buffer.getvalue()
    return text[text.index("<svg") :]


#: Resolution of the report's figures (dots per inch at print size: 180 mm wide is 1063 px).
REPORT_DPI = 150


def png_bytes(plot: Plot, dpi: int = REPORT_DPI) -> bytes:
    """The figure as PNG, drawn once per resolution (kept on the figure: the HTML and the PDF share it).

    An RGB image (the figures are opaque), written by :func:`bench.reports.png.rgb_png`: the PDF embeds its
    compressed pixels as they are; matplotlib's own PNG keeps an alpha channel that the PDF would split off and
    compress as a second image."""
    rendered = plot.figure.__dict__.setdefault("_bench_png", {})
    if dpi not in rendered:
        buffer = io.BytesIO()
        plot.figure.savefig(buffer, format="rgba", dpi=dpi)
        width, height = (int(side) for side in plot.figure.get_size_inches() * dpi)  # the Agg canvas's size
        rendered[dpi] = rgb_png(buffer.getbuffer(), width, height, dpi)
    return rendered[dpi]


def _panel_count(figure: Figure) -> int:
    """The panels a figure draws: a :class:`SmallMultiples` figure's panels (all in one Axes), else its Axes."""
    grid = getattr(figure, "_bench_small_multiples", None)
    return len(grid.panels) if grid is not None else max(1, len(figure.axes))


def _spare_core() -> bool:
    """Whether another process would get a core of its own now (the 1-minute load, this process included, leaves
    one free): on the shared 2-core bench PC under load a second drawing process only competes with the first."""
    return os.getloadavg()[0] <= (os.cpu_count() or 1) - 1


def draw_all(plots, dpi: int = REPORT_DPI, *, parallel: bool | None = None) -> None:
    """Draw the PNG of every plot (:func:`png_bytes`), about half of them in one forked process while this one
    draws the rest: drawing is most of a report's time, and figures share nothing. ``parallel`` None: when a core
    is spare (:func:`_spare_core`). Only from a process with a single thread (a fork copies one thread; another's
    lock could never be released in the child) on a system with ``fork``; a figure the child did not return (it
    failed or was killed) is drawn here, so the result is the same PNG either way, only later."""
    pending = [plot for plot in plots if dpi not in plot.figure.__dict__.get("_bench_png", {})]
    if parallel is None:
        parallel = hasattr(os, "getloadavg") and _spare_core()
    if not parallel or len(pending) < 2 or not hasattr(os, "fork") or threading.active_count() > 1:
        for plot in pending:
            png_bytes(plot, dpi)
        return
    # balance by the number of panels (they cost about the same each)
    mine, theirs, load = [], [], [0, 0]
    for plot in sorted(pending, key=lambda p: -_panel_count(p.figure)):
        side = 0 if load[0] <= load[1] else 1
        (mine, theirs)[side].append(plot)
        load[side] += _panel_count(plot.figure)
    readable, writable = os.pipe()
    child = os.fork()
    if child == 0:  # the child: draw its share, send the PNGs, leave without running any exit handler
        status = 1
        try:
            os.close(readable)
            with os.fdopen(writable, "wb") as pipe:
                pickle.dump([png_bytes(plot, dpi) for plot in theirs], pipe)
            status = 0
        finally:
            os._exit(status)
    os.close(writable)
    for plot in mine:
        png_bytes(plot, dpi)
    with os.fdopen(readable, "rb") as pipe:
        try:
            images = pickle.load(pipe)
        except (EOFError, pickle.UnpicklingError):
            images = []
    os.waitpid(child, 0)
    for plot, image in zip(theirs, images):
        plot.figure.__dict__.setdefault("_bench_png", {})[dpi] = image
    for plot in theirs[len(images) :]:
        png_bytes(plot, dpi)


def _rows_of(report: RunReport, result, columns: list[str]) -> np.ndarray:
    """The values of ``columns`` (rows, columns) of the samples of ``result`` (its pose and conditions), in cycle
    order; numpy masks on the table's columns (pandas' boolean indexing cost a report 50 ms for 45 selections)."""
    table = report.table
    mask = table["pose"].to_numpy() == result.pose
    for name, value in result.conditions:
        mask &= table[name].to_numpy() == value
    order = np.argsort(table["cycle"].to_numpy()[mask], kind="stable")
    return np.column_stack([table[column].to_numpy()[mask][order] for column in columns])


def panels(count: int, *, max_columns: int, size: tuple[float, float] = (2.6, 2.6)) -> tuple[Figure, list]:
    """A figure with ``count`` small panels, ``max_columns`` per row at most, each ``size`` inches before the
    figure is scaled to the print width (:func:`print_ready`), each panel on its own scale. Small multiples on one
    scale are :class:`bench.reports.small_multiples.SmallMultiples`."""
    columns = max(1, min(max_columns, count))
    rows = math.ceil(count / columns)
    figure = Figure(figsize=(size[0] * columns, size[1] * rows + 0.4), layout="constrained")
    return figure, [figure.add_subplot(rows, columns, index + 1) for index in range(count)]


def _short_label(result) -> str:
    """``P1`` or ``P1, 100 %`` (panel titles: the conditions in short words)."""
    from bench.metrology.formatting import pose_label

    return pose_label(result.pose, result.conditions).replace(" velocity", "").replace(" load", "")


def _measured(result) -> tuple[np.ndarray, list[str]]:
    """The command on the measured axes and their columns (an instrument may read a subset, e.g. x, y)."""
    columns = [f"{a}_mm" for a in result.axis_names]
    return np.asarray(result.commanded_mm)[["xyz".index(a) for a in result.axis_names]], columns


def print_grid(
    count: int,
    panel_size: tuple[float, float],
    *,
    max_columns: int = 5,
    equal_aspect: bool = False,
    y_log: bool = False,
) -> SmallMultiples:
    """A report's small multiples at print width in the smallest print font (five panels a row unless told)."""
    return SmallMultiples(
        count,
        max_columns=max_columns,
        panel_size=panel_size,
        width_in=PRINT_WIDTH_IN,
        font_pt=MIN_FONT_PT,
        equal_aspect=equal_aspect,
        y_log=y_log,
    )


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


def payload_shift_figure(series) -> tuple[Figure, list]:
    """|PE(m)| and its z component (sag) against load, one line per ``(label, PayloadShift)`` of ``series``;
    returns the figure and its two axes (norm, sag) for additions."""
    figure = Figure(figsize=(10, 3.8), layout="constrained")
    norm, sag = figure.add_subplot(1, 2, 1), figure.add_subplot(1, 2, 2)
    for label, shift in series:
        norm.plot(shift.load_kg, shift.shift_norm_mm, marker="o", label=label)
        if shift.shift_mm.shape[1] > 2:
            sag.plot(shift.load_kg, shift.shift_mm[:, 2], marker="o", label=label)
    for axes, label in ((norm, "|PE(m)| (mm)"), (sag, "PE_z(m) (mm)")):
        axes.set_xlabel("load (kg)")
        axes.set_ylabel(label)
    return figure, [norm, sag]


def payload_caption(reference_load_kg: float) -> str:
    return (
        f"Payload error PE(m) = x̄(m) − x̄(m₀) against load, m₀ = {reference_load_kg:g} kg (project definition, "
        f"iso9283.md §12)."
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


def nonnegative_yerr(values, errors) -> list[list[float]]:
    """Error bars ``value ± U`` of a figure that cannot be negative (AP_P, RP_l: lengths of vectors): the lower bar
    stops at 0 mm (lower = min(U, value)), the upper one is U; matplotlib's ``yerr`` as [lower, upper]."""
    values = np.nan_to_num(np.asarray(values, dtype=float))
    errors = np.asarray(errors, dtype=float)
    return [list(np.minimum(errors, np.maximum(values, 0.0))), list(errors)]


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
