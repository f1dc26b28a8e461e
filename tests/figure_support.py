"""What the report figures look like on paper: the printed size of every text (shared by the figure tests)."""

from __future__ import annotations

from matplotlib.text import Text

from bench.reports.plots import PRINT_HEIGHT_IN, PRINT_WIDTH_IN, svg_text


def printed_font_sizes(plot) -> list[float]:
    """Point size on A4 of every text drawn in the figure (the PDF fits the figure into 180 x 200 mm)."""
    svg_text(plot)  # draw: tick labels exist after a draw
    width, height = plot.figure.get_size_inches()
    scale = min(PRINT_WIDTH_IN / width, PRINT_HEIGHT_IN / height)
    return [text.get_fontsize() * scale for text in plot.figure.findobj(Text)
            if text.get_visible() and text.get_text().strip()]
