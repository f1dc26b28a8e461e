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

from bench.reports.cores import spare_core
from bench.reports.png import rgb_png
from bench.reports.small_multiples import SmallMultiples, legend_entries

__all__ = [
    "MIN_FONT_PT",
    "PRINT_HEIGHT_IN",
    "PRINT_WIDTH_IN",
    "Plot",
    "REPORT_DPI",
    "draw_all",
    "legend_entries",
    "print_grid",
    "print_ready",
    "panels",
    "payload_caption",
    "payload_shift_figure",
    "png_bytes",
    "svg_text",
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


def draw_all(plots, dpi: int = REPORT_DPI, *, parallel: bool | None = None) -> None:
    """Draw the PNG of every plot (:func:`png_bytes`), about half of them in one forked process while this one
    draws the rest: drawing is most of a report's time, and figures share nothing. ``parallel`` None: when a core
    is spare (:func:`bench.reports.cores.spare_core`). Only from a process with a single thread (a fork copies one thread; another's
    lock could never be released in the child) on a system with ``fork``; a figure the child did not return (it
    failed or was killed) is drawn here, so the result is the same PNG either way, only later."""
    pending = [plot for plot in plots if dpi not in plot.figure.__dict__.get("_bench_png", {})]
    if parallel is None:
        parallel = spare_core()
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


def panels(count: int, *, max_columns: int, size: tuple[float, float] = (2.6, 2.6)) -> tuple[Figure, list]:
    """A figure with ``count`` small panels, ``max_columns`` per row at most, each ``size`` inches before the
    figure is scaled to the print width (:func:`print_ready`), each panel on its own scale. Small multiples on one
    scale are :class:`bench.reports.small_multiples.SmallMultiples`."""
    columns = max(1, min(max_columns, count))
    rows = math.ceil(count / columns)
    figure = Figure(figsize=(size[0] * columns, size[1] * rows + 0.4), layout="constrained")
    return figure, [figure.add_subplot(rows, columns, index + 1) for index in range(count)]


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


def nonnegative_yerr(values, errors) -> list[list[float]]:
    """Error bars ``value ± U`` of a figure that cannot be negative (AP_P, RP_l: lengths of vectors): the lower bar
    stops at 0 mm (lower = min(U, value)), the upper one is U; matplotlib's ``yerr`` as [lower, upper]."""
    values = np.nan_to_num(np.asarray(values, dtype=float))
    errors = np.asarray(errors, dtype=float)
    return [list(np.minimum(errors, np.maximum(values, 0.0))), list(errors)]
