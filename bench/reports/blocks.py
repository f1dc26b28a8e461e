"""The blocks a report document is made of (sections of paragraphs, tables and figures), which both renderers walk.

Their own module, below every layout: a layout (:mod:`bench.reports.document`, :mod:`bench.reports.orientation`,
:mod:`bench.reports.signature`) builds them, the HTML template and the PDF builder print them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from bench.reports.plots import Plot

__all__ = ["Block", "Document", "Figure", "Paragraph", "RawData", "Section", "Table"]


@dataclass(frozen=True)
class Paragraph:
    text: str
    verbatim: bool = False  #: a command to type: printed as written (module names kept; local paths still removed)


@dataclass(frozen=True)
class Table:
    ident: str  #: HTML id, e.g. "results"
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str = ""
    #: the least height of a body row, mm (0: as its text needs); a signature row is written on by hand
    row_height_mm: float = 0.0
    #: relative column widths (empty: from the longest text of each column)
    column_weights: tuple[float, ...] = ()


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
