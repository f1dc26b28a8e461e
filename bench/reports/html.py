"""Render a report :class:`~bench.reports.document.Document` as one self-contained HTML file.

Jinja2 template ``templates/report.html.j2`` with autoescaping; figures are inlined as PNG data URIs (the same
image as the PDF's, drawn once; see :mod:`bench.reports.plots`), at their print width, with the caption as the
alternative text; styles are inline and there is no script, so the file can be mailed or archived alone.
"""

from __future__ import annotations

import base64
from pathlib import Path

from jinja2 import Environment, PackageLoader, select_autoescape

from bench.reports.document import Document, Figure, Paragraph, Table
from bench.reports.plots import png_bytes

__all__ = ["render_html", "write_html"]

_ENVIRONMENT = Environment(
    loader=PackageLoader("bench.reports", "templates"),
    autoescape=select_autoescape(["html", "j2"]),
    trim_blocks=True,
    lstrip_blocks=True,
)


def _block(block) -> dict:
    if isinstance(block, Paragraph):
        return {"kind": "paragraph", "text": block.text}
    if isinstance(block, Table):
        return {
            "kind": "table",
            "ident": block.ident,
            "header": block.header,
            "rows": block.rows,
            "caption": block.caption,
            "row_height_mm": block.row_height_mm,
            "widths_pct": [round(100 * w / sum(block.column_weights), 1) for w in block.column_weights],
        }
    if isinstance(block, Figure):
        width_in, _ = block.plot.figure.get_size_inches()
        return {
            "kind": "figure",
            "png": base64.b64encode(png_bytes(block.plot)).decode("ascii"),
            "width_mm": round(width_in * 25.4, 1),
            "caption": block.plot.caption,
        }
    raise TypeError(f"unknown report block {block!r}")


def render_html(document: Document) -> str:
    """The HTML text of ``document``."""
    sections = [{"title": s.title, "blocks": [_block(b) for b in s.blocks]} for s in document.sections]
    view = {
        "title": document.title,
        "subtitle": document.subtitle,
        "sections": sections,
        "banner": document.meta.get("banner"),
    }
    return _ENVIRONMENT.get_template("report.html.j2").render(doc=view)


def write_html(document: Document, path: str | Path) -> Path:
    path = Path(path)
    path.write_text(render_html(document), encoding="utf-8")
    return path
