"""Small multiples on one scale, drawn as one matplotlib Axes: panels are boxes of that Axes, each mapping the
shared limits onto its box, with one set of tick positions and labels computed once for all of them.

Why not one Axes per panel: matplotlib's fixed cost per Axes (construction, two axes with their tick objects, each
tick label laid out per draw) is most of a 15-panel figure's time, and every panel of a small multiple has the same
scale, so the same ticks. What the reader sees is the same: a frame per panel with tick marks on its bottom and left
edges, tick labels on the outer panels (the left column, and the lowest panel of each column), a title per panel,
every panel on one x and one y scale.

The figure is drawn at print width (:data:`bench.reports.plots.PRINT_WIDTH_IN`), so a point is a point on paper.
The Axes' own coordinates are inches of the panel area (origin at its lower left); a panel's transform maps its
data (in the shared limits) into its box.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle
from matplotlib.scale import LogTransform
from matplotlib.ticker import LogLocator, MaxNLocator
from matplotlib.transforms import Affine2D, Bbox, IdentityTransform, TransformedBbox, blended_transform_factory

__all__ = ["Panel", "SmallMultiples", "legend_entries"]

#: matplotlib's defaults for what is drawn here by hand (rcParams xtick.major.size/pad, axes.linewidth,
#: axes.xmargin, axes.titlepad is replaced by 2 pt as the report's panels had), points and fractions.
_TICK_PT, _TICK_PAD_PT, _FRAME_PT, _MARGIN, _TITLE_PAD_PT = 3.5, 3.5, 0.8, 0.05, 2.0
_MINOR_TICK_PT = 2.0  #: rcParams ytick.minor.size


def legend_entries(axes_list) -> dict:
    """Each label of the panels ``axes_list`` once (its first handle), in the order first met: the entries of the
    one legend a figure of small multiples gets."""
    entries: dict = {}
    for axes in axes_list:
        for handle, label in zip(*axes.get_legend_handles_labels()):
            entries.setdefault(label, handle)
    return entries


class Panel:
    """One panel: draws into the grid's Axes in its own data coordinates (the shared limits), clipped to its box."""

    def __init__(self, grid: SmallMultiples, row: int, column: int):
        self.grid, self.row, self.column = grid, row, column
        self._to_box = Affine2D()  # data -> inches of the panel area, set once the limits are known (finish)
        # a log y scale maps y to log10(y) first (values <= 0 fall far below the panel and are clipped, as on a
        # matplotlib log axis)
        to_box = (
            blended_transform_factory(IdentityTransform(), LogTransform(10)) + self._to_box
            if grid.y_log
            else self._to_box
        )
        self.transform = to_box + grid.axes.transData
        # (min, max, smallest positive) of the finite values of each artist drawn, per axis: the shared limits
        self.x_extent: list[tuple[float, float, float]] = []
        self.y_extent: list[tuple[float, float, float]] = []
        self.title = ""
        self._unstyled_lines = 0
        self.artists: list = []  # what the panel drew, in order

    @property
    def box_in(self) -> tuple[float, float, float, float]:
        """(x0, y0, width, height) of the panel's frame, inches from the lower left of the panel area."""
        g = self.grid
        x0 = g.x_offset_in + self.column * (g.panel_width_in + g.gap_width_in)
        y0 = (g.rows - 1 - self.row) * (g.panel_height_in + g.gap_height_in)
        return x0, y0, g.panel_width_in, g.panel_height_in

    def _placed(self, artist, x=(), y=()):
        for values, extent in ((x, self.x_extent), (y, self.y_extent)):
            values = np.ravel(np.asarray(values, dtype=float))
            values = values[np.isfinite(values)]
            if len(values):
                positive = values[values > 0]
                extent.append(
                    (float(values.min()), float(values.max()), float(positive.min()) if len(positive) else math.nan)
                )
        x0, y0, width, height = self.box_in
        artist.set_clip_box(TransformedBbox(Bbox.from_bounds(x0, y0, width, height), self.grid.axes.transData))
        self.artists.append(artist)
        return artist

    def _add(self, artist):
        """``artist`` on the grid's Axes without updating its data limits (fixed: the panels' boxes, in inches),
        which for a line or a circle in a panel's own transform cost more than building it. Unlabelled, it is
        left out of legends as ``Axes.plot`` leaves it (a label starting with "_")."""
        if not artist.get_label():
            artist.set_label("_nolegend_")
        return self.grid.axes.add_artist(artist)

    def _line(self, x, y, transform, **kwargs) -> Line2D:
        x, y = (np.atleast_1d(np.asarray(values, dtype=float)) for values in (x, y))
        return self._add(Line2D(x, y, transform=transform, **kwargs))

    def plot(self, x, y, **kwargs):
        """A line (``Axes.plot`` keywords); its points count for the shared limits. Without a colour, the next of
        the panel's own colour cycle (C0, C1, ...), so the n-th series has one colour in every panel."""
        if "color" not in kwargs and "c" not in kwargs:
            kwargs["color"] = f"C{self._unstyled_lines % 10}"
            self._unstyled_lines += 1
        return self._placed(self._line(x, y, self.transform, **kwargs), x, y)

    def scatter(self, x, y, **kwargs):
        return self._placed(self.grid.axes.scatter(x, y, transform=self.transform, **kwargs), x, y)

    def circle(self, centre, radius: float, **kwargs):
        """A circle in data units (round on paper when the grid's x and y scales are equal)."""
        patch = self._add(Circle(centre, radius, transform=self.transform, **kwargs))
        return self._placed(patch, [centre[0] - radius, centre[0] + radius], [centre[1] - radius, centre[1] + radius])

    def step_histogram(self, values, edges, **kwargs) -> np.ndarray:
        """The histogram of ``values`` over ``edges`` as a step outline from 0 (``histtype="step"``); the counts."""
        counts, _ = np.histogram(values, bins=edges)
        x = np.repeat(edges, 2)
        y = np.concatenate([[0.0], np.repeat(counts, 2), [0.0]])
        self.plot(x, y, **kwargs)
        self.grid.y_floor = 0.0  # counts start at 0, with no margin below (as matplotlib's hist)
        return counts

    def vline(self, x: float, **kwargs):
        """A vertical line across the panel at data ``x`` (which counts for the x limits only)."""
        x0, y0, width, height = self.box_in
        across = Affine2D().scale(1.0, height).translate(0.0, y0) + self.grid.axes.transData
        line = self._line([x, x], [0.0, 1.0], blended_transform_factory(self.transform, across), **kwargs)
        return self._placed(line, [x], [])

    def hline(self, y: float, **kwargs):
        """A horizontal line across the panel at data ``y`` (which counts for the y limits only)."""
        x0, y0, width, height = self.box_in
        across = Affine2D().scale(width, 1.0).translate(x0, 0.0) + self.grid.axes.transData
        line = self._line([0.0, 1.0], [y, y], blended_transform_factory(across, self.transform), **kwargs)
        return self._placed(line, [], [y])

    def annotate(self, text: str, xy, *, offset_pt=(3, 3), **kwargs):
        """``text`` beside the data point ``xy``, ``offset_pt`` points away (not counted for the limits)."""
        label = self.grid.axes.annotate(
            text,
            xy,
            xycoords=self.transform,
            xytext=offset_pt,
            textcoords="offset points",
            annotation_clip=False,
            **kwargs,
        )
        self.artists.append(label)
        return label

    def set_title(self, text: str) -> None:
        self.title = text


class SmallMultiples:
    """``count`` panels, ``max_columns`` per row, on ``width_in`` (the print width); ``panel_size`` (width, height)
    the proportions of a panel's cell (the panel and its share of the gaps, fractions ``gaps`` of a panel, as
    matplotlib's subplots_adjust wspace/hspace); ``equal_aspect``: square panels, so one x and y scale reads true;
    ``y_log``: a log y scale. One x and one y scale for all panels (``xlim``/``ylim`` set before :meth:`finish`, or
    the data limits with 5 % margins); ``x_locator``/``y_locator``: tick positions (default: matplotlib's automatic
    choice for the panel's size)."""

    def __init__(
        self,
        count: int,
        *,
        max_columns: int,
        panel_size: tuple[float, float],
        width_in: float,
        margins_in: tuple[float, float, float, float] = (0.62, 0.08, 0.5, 0.5),
        gaps: tuple[float, float] = (0.12, 0.32),
        font_pt: float = 7.0,
        y_log: bool = False,
        equal_aspect: bool = False,
    ):
        if count < 1:
            raise ValueError(f"count = {count}, expected at least one panel")
        self.font_pt, self.y_log = font_pt, y_log
        self.columns = max(1, min(max_columns, count))
        self.rows = math.ceil(count / self.columns)
        left, right, bottom, top = margins_in
        area_width = width_in - left - right
        area_height = area_width * self.rows * panel_size[1] / (self.columns * panel_size[0])  # cells + gaps
        self.panel_width_in = area_width / (self.columns + (self.columns - 1) * gaps[0])
        self.panel_height_in = area_height / (self.rows + (self.rows - 1) * gaps[1])
        self.gap_width_in = gaps[0] * self.panel_width_in
        self.gap_height_in = gaps[1] * self.panel_height_in
        self.x_offset_in = 0.0
        if equal_aspect:  # square panels (one scale for x and y reads true), the grid centred in the width
            self.panel_width_in = self.panel_height_in = min(self.panel_width_in, self.panel_height_in)
            used = self.columns * self.panel_width_in + (self.columns - 1) * self.gap_width_in
            self.x_offset_in = (area_width - used) / 2
        height_in = area_height + bottom + top
        self.figure = Figure(figsize=(width_in, height_in))
        self.axes = self.figure.add_axes(
            (left / width_in, bottom / height_in, area_width / width_in, area_height / height_in)
        )
        self.axes.set_xlim(0.0, area_width)
        self.axes.set_ylim(0.0, area_height)
        self.axes.set_axis_off()  # frames, ticks and labels are drawn per panel (finish)
        self.panels = [Panel(self, index // self.columns, index % self.columns) for index in range(count)]
        self.xlim: tuple[float, float] | None = None
        self.ylim: tuple[float, float] | None = None
        self.x_locator = self.y_locator = None
        self.y_floor: float | None = None
        self.figure._bench_small_multiples = self

    def finish(
        self,
        xlabel: str,
        ylabel: str,
        *,
        legend_columns: int | None = None,
        legend_pt: float | None = None,
        legend_order=None,
    ) -> Figure:
        """Fix the shared limits, map every panel's data into its box, draw frames, ticks, tick labels and titles;
        name the quantities once for the figure and give it one legend on top (each label once, in the order first
        drawn, or sorted by ``legend_order``, a key on the label; ``legend_columns`` a row, default all)."""
        self._place()
        size = self.font_pt + 1 if legend_pt is None else legend_pt
        self.figure.supxlabel(xlabel, fontsize=self.font_pt + 1, y=0.005, va="bottom")
        self.figure.supylabel(ylabel, fontsize=self.font_pt + 1, x=0.005, ha="left")
        entries = legend_entries([self.axes])
        labels = sorted(entries, key=legend_order) if legend_order else list(entries)
        if labels:
            self.figure.legend(
                [entries[label] for label in labels],
                labels,
                loc="upper center",
                ncols=min(legend_columns or len(labels), len(labels)),
                fontsize=size,
            )
        return self.figure

    def _place(self) -> None:
        xlim = self.xlim or self._data_limits([(low, high) for p in self.panels for low, high, _ in p.x_extent], None)
        y_values = [(low, high) for p in self.panels for low, high, _ in p.y_extent]
        if self.y_log:  # limits, margins and ticks in log10(y), as on a matplotlib log axis
            y_values = [
                (math.log10(positive), math.log10(high))
                for p in self.panels
                for _, high, positive in p.y_extent
                if positive > 0
            ]
        ylim = self.ylim or self._data_limits(y_values, self.y_floor, back=(lambda v: 10.0**v) if self.y_log else None)
        low, high = self._y_scaled(ylim)
        for panel in self.panels:
            x0, y0, width, height = panel.box_in
            panel._to_box.clear().translate(-xlim[0], -low).scale(
                width / (xlim[1] - xlim[0]), height / (high - low)
            ).translate(x0, y0)
        self.xlim, self.ylim = xlim, ylim
        x_ticks = self._ticks(xlim, self.x_locator, self.panel_width_in * 72 / (3 * self.font_pt))
        if self.y_log:
            y_ticks, y_labels, y_minor = self._log_ticks(ylim)
        else:
            y_ticks = self._ticks(ylim, self.y_locator, self.panel_height_in * 72 / (2 * self.font_pt))
            y_labels, y_minor = self._labels(y_ticks), np.array([])
        self._draw_frames_and_ticks(x_ticks, self._labels(x_ticks), y_ticks, y_labels, y_minor)

    def _y_scaled(self, values) -> np.ndarray:
        """y values in the panels' vertical measure: log10(y) on a log scale, else y."""
        values = np.asarray(values, dtype=float)
        return np.log10(values) if self.y_log else values

    @staticmethod
    def _log_ticks(limits) -> tuple[np.ndarray, list[str], np.ndarray]:
        """Decades labelled 10^k and the unlabelled 2..9 between them (matplotlib's LogLocator and its
        LogFormatterSciNotation); under two decades in range, every one of them labelled with its value."""

        def within(ticks):
            ticks = np.asarray(ticks, dtype=float)
            return ticks[(ticks >= limits[0] * (1 - 1e-9)) & (ticks <= limits[1] * (1 + 1e-9))]

        major = within(LogLocator(base=10.0).tick_values(*limits))
        minor = within(LogLocator(base=10.0, subs=np.arange(2, 10)).tick_values(*limits))
        if len(major) < 2:
            ticks = np.union1d(major, minor)
            return ticks, [f"{t:g}" for t in ticks], np.array([])
        exponents = np.round(np.log10(major)).astype(int)
        return major, [f"$\\mathdefault{{10^{{{e}}}}}$" for e in exponents], minor

    @staticmethod
    def _data_limits(extents: Sequence[tuple[float, float]], floor: float | None, back=None) -> tuple[float, float]:
        """Limits over every panel's (low, high) extents with 5 % margins (``floor``: the low limit, no margin
        below); ``back`` maps the limits back to data units when the extents were scaled (log10)."""
        values = np.array([v for extent in extents for v in extent], dtype=float)
        low, high = (float(values.min()), float(values.max())) if len(values) else (0.0, 1.0)
        if high == low:
            low, high = low - 0.5, high + 0.5
        pad = _MARGIN * (high - low)
        low, high = (low - pad if floor is None else floor), high + pad
        return (float(back(low)), float(back(high))) if back else (low, high)

    @staticmethod
    def _ticks(limits, locator, tick_space: float) -> np.ndarray:
        """Tick positions within ``limits``: ``locator``'s, else matplotlib's automatic choice (MaxNLocator with
        as many bins as fit the panel: 3 label heights per x tick, 2 per y tick, at most 9)."""
        locator = locator or MaxNLocator(nbins=int(np.clip(math.floor(tick_space), 1, 9)), steps=[1, 2, 2.5, 5, 10])
        ticks = np.asarray(locator.tick_values(*limits), dtype=float)
        span = limits[1] - limits[0]
        return ticks[(ticks >= limits[0] - 1e-9 * span) & (ticks <= limits[1] + 1e-9 * span)]

    @staticmethod
    def _labels(ticks: np.ndarray) -> list[str]:
        """The labels matplotlib's ScalarFormatter gives evenly spaced ticks: the fewest decimals that show every
        tick exactly, the same for all, "−" for negatives, and 0 unsigned."""
        span = float(np.ptp(ticks)) if len(ticks) > 1 else max(abs(float(ticks[0])), 1.0) if len(ticks) else 1.0
        decimals = next((d for d in range(12) if np.allclose(np.round(ticks, d), ticks, rtol=0, atol=1e-6 * span)), 12)
        labels = []
        for value in ticks:
            text = f"{value:.{decimals}f}"
            labels.append(text.lstrip("-") if float(text) == 0 else text.replace("-", "\N{MINUS SIGN}"))
        return labels

    def _draw_frames_and_ticks(self, x_ticks, x_labels, y_ticks, y_labels, y_minor) -> None:
        axes, tick, minor_tick = self.axes, _TICK_PT / 72, _MINOR_TICK_PT / 72
        low, high = self._y_scaled(self.ylim)
        lowest = {}  # the lowest panel of each column gets the x tick labels
        for panel in self.panels:
            lowest[panel.column] = panel
        frames, marks = [], []
        for panel in self.panels:
            x0, y0, width, height = panel.box_in
            frames.append([(x0, y0), (x0 + width, y0), (x0 + width, y0 + height), (x0, y0 + height), (x0, y0)])
            xs = x0 + (x_ticks - self.xlim[0]) * width / (self.xlim[1] - self.xlim[0])
            ys = y0 + (self._y_scaled(y_ticks) - low) * height / (high - low)
            marks.extend([[(x, y0), (x, y0 - tick)] for x in xs])
            marks.extend([[(x0, y), (x0 - tick, y)] for y in ys])
            if len(y_minor):
                marks.extend(
                    [
                        [(x0, y), (x0 - minor_tick, y)]
                        for y in y0 + (self._y_scaled(y_minor) - low) * height / (high - low)
                    ]
                )
            if lowest[panel.column] is panel:
                for x, label in zip(xs, x_labels):
                    axes.text(
                        x, y0 - (_TICK_PT + _TICK_PAD_PT) / 72, label, ha="center", va="top", fontsize=self.font_pt
                    )
            if panel.column == 0:
                for y, label in zip(ys, y_labels):
                    axes.text(
                        x0 - (_TICK_PT + _TICK_PAD_PT) / 72, y, label, ha="right", va="center", fontsize=self.font_pt
                    )
            if panel.title:
                axes.text(
                    x0 + width / 2,
                    y0 + height + _TITLE_PAD_PT / 72,
                    panel.title,
                    ha="center",
                    va="baseline",
                    fontsize=self.font_pt,
                )
        axes.add_collection(
            LineCollection(
                frames,
                colors="black",
                linewidths=_FRAME_PT,
                capstyle="projecting",
                joinstyle="miter",
                zorder=2.5,
                clip_on=False,
            )
        )  # edges on the rim
        axes.add_collection(LineCollection(marks, colors="black", linewidths=_FRAME_PT, clip_on=False, zorder=2.5))
