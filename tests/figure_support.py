"""What the report figures look like on paper: the printed size of every text (shared by the figure tests)."""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.text import Text

from bench.reports.plots import PRINT_HEIGHT_IN, PRINT_WIDTH_IN, svg_text


def printed_font_sizes(plot) -> list[float]:
    """Point size on A4 of every text drawn in the figure (the PDF fits the figure into 180 x 200 mm)."""
    svg_text(plot)  # draw: tick labels exist after a draw
    width, height = plot.figure.get_size_inches()
    scale = min(PRINT_WIDTH_IN / width, PRINT_HEIGHT_IN / height)
    return [
        text.get_fontsize() * scale
        for text in plot.figure.findobj(Text)
        if text.get_visible() and text.get_text().strip()
    ]


def small_multiples(plot):
    """The grid of a small-multiples figure (bench.reports.small_multiples) and its panels."""
    grid = plot.figure._bench_small_multiples
    return grid, grid.panels


def panel_lines(panel) -> list:
    """The lines a panel drew (curves, marks, reference lines)."""
    return [artist for artist in panel.artists if isinstance(artist, Line2D)]


def same_scale(grid) -> bool:
    """Whether one data point lies at the same place in every panel's frame (display units from its lower left
    corner), and a panel's lower-left limits at that corner: one x and one y scale, as the reader compares them."""
    corners = np.array([[grid.xlim[0], grid.ylim[0]], [grid.xlim[1], grid.ylim[1]]])
    places = [panel.transform.transform(corners) - panel.transform.transform(corners[:1]) for panel in grid.panels]
    frames = [grid.axes.transData.transform(np.array(panel.box_in[:2])) for panel in grid.panels]
    starts = [panel.transform.transform(corners[:1])[0] - frame for panel, frame in zip(grid.panels, frames)]
    return all(np.allclose(p, places[0]) for p in places) and np.allclose(starts, 0.0, atol=1e-6)
