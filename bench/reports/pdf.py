"""Render a report :class:`~bench.reports.document.Document` as a PDF with reportlab (no browser involved).

The same sections, paragraphs, tables and figures as the HTML, on A4 pages numbered "page i of n" with the
report id in the footer. Text uses the DejaVu Sans fonts shipped with matplotlib (±, −, Δ, °, x̄ need more than
the PDF core fonts' Latin-1); figures are the report's PNGs at 150 dpi (the HTML inlines the same images), their
compressed pixels embedded as they are (:class:`_Png`).
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path
from xml.sax.saxutils import escape

import matplotlib
from reportlab.lib import colors
from reportlab.lib.enums import TA_LEFT
from reportlab.lib.pagesizes import A4
from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet
from reportlab.lib.units import mm
from reportlab.pdfbase import pdfdoc, pdfmetrics
from reportlab.pdfbase.ttfonts import TTFont
from reportlab.pdfgen import canvas as pdf_canvas
from reportlab.platypus import (
    Flowable,
    Image,
    KeepTogether,
    SimpleDocTemplate,
    Spacer,
    TableStyle,
)
from reportlab.platypus import Paragraph as PdfParagraph
from reportlab.platypus import Table as PdfTable

from bench.reports.document import Document, Figure, Paragraph, Table
from bench.reports.plots import png_bytes
from bench.reports.png import DeflatedRgb, deflated_rgb

__all__ = ["render_pdf", "write_pdf"]

_FONT, _BOLD = "DejaVuSans", "DejaVuSans-Bold"


def _register_fonts() -> None:
    if _FONT in pdfmetrics.getRegisteredFontNames():
        return
    folder = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
    pdfmetrics.registerFont(TTFont(_FONT, str(folder / "DejaVuSans.ttf")))
    pdfmetrics.registerFont(TTFont(_BOLD, str(folder / "DejaVuSans-Bold.ttf")))
    pdfmetrics.registerFontFamily(_FONT, normal=_FONT, bold=_BOLD, italic=_FONT, boldItalic=_BOLD)


def _styles() -> dict[str, ParagraphStyle]:
    base = getSampleStyleSheet()
    return {
        "title": ParagraphStyle("title", parent=base["Title"], fontName=_BOLD, fontSize=16, leading=20),
        "subtitle": ParagraphStyle(
            "subtitle", parent=base["Normal"], fontName=_FONT, fontSize=9, textColor=colors.HexColor("#555555")
        ),
        "h2": ParagraphStyle(
            "h2", parent=base["Heading2"], fontName=_BOLD, fontSize=12, textColor=colors.HexColor("#2b5797")
        ),
        "body": ParagraphStyle("body", parent=base["Normal"], fontName=_FONT, fontSize=9, leading=12),
        "cell": ParagraphStyle("cell", fontName=_FONT, fontSize=6.5, leading=8, alignment=TA_LEFT),
        "head": ParagraphStyle("head", fontName=_BOLD, fontSize=6.5, leading=8, alignment=TA_LEFT),
        "caption": ParagraphStyle(
            "caption",
            parent=base["Normal"],
            fontName=_FONT,
            fontSize=8,
            leading=10,
            textColor=colors.HexColor("#444444"),
        ),
    }


class _NumberedCanvas(pdf_canvas.Canvas):
    """Defers each page so the footer can say "page i of n"."""

    footer = ""
    banner = ""  #: drawn across the top of every page when set (simulated data)

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._pages = []

    def showPage(self):
        self._pages.append(dict(self.__dict__))
        self._startPage()

    def save(self):
        for state in self._pages:
            self.__dict__.update(state)
            self.setFont(_FONT, 7)
            self.drawString(15 * mm, 10 * mm, self.footer)
            self.drawRightString(A4[0] - 15 * mm, 10 * mm, f"page {self._pageNumber} of {len(self._pages)}")
            if self.banner:
                self.setFillColor(colors.HexColor("#b00020"))
                self.rect(0, A4[1] - 11 * mm, A4[0], 7 * mm, stroke=0, fill=1)
                self.setFillColor(colors.white)
                self.setFont(_BOLD, 9)
                self.drawCentredString(A4[0] / 2, A4[1] - 8.6 * mm, self.banner)
                self.setFillColor(colors.black)
            super().showPage()
        super().save()


def _column_widths(block: Table, width: float) -> list[float]:
    """Widths proportional to each column's longest text (capped), but never narrower than its longest word."""
    columns = list(zip(block.header, *block.rows))
    weights = [min(max(len(c) for c in column), 60) for column in columns]
    floors = [
        max(pdfmetrics.stringWidth(word, _BOLD, 6.5) for c in column for word in (c.split() or [""])) + 6
        for column in columns
    ]
    widths = [width * w / sum(weights) for w in weights]
    narrow = {i for i, (w, f) in enumerate(zip(widths, floors)) if w < f}
    if sum(floors[i] for i in narrow) > 0.8 * width:  # unbreakable text everywhere: keep proportions, let it wrap
        return widths
    free = width - sum(floors[i] for i in narrow)
    rest = sum(weights[i] for i in range(len(columns)) if i not in narrow) or 1
    return [floors[i] if i in narrow else free * weights[i] / rest for i in range(len(columns))]


def _table(block: Table, styles, width: float) -> list:
    header = [PdfParagraph(escape(c), styles["head"]) for c in block.header]
    rows = [[PdfParagraph(escape(c), styles["cell"]) for c in row] for row in block.rows]
    if block.column_weights:
        widths = [width * w / sum(block.column_weights) for w in block.column_weights]
    else:
        widths = _column_widths(block, width)
    heights = [None] + [block.row_height_mm * mm or None] * len(rows)
    table = PdfTable([header, *rows], colWidths=widths, rowHeights=heights, repeatRows=1)
    table.setStyle(
        TableStyle(
            [
                ("GRID", (0, 0), (-1, -1), 0.4, colors.HexColor("#b8c2d6")),
                ("BACKGROUND", (0, 0), (-1, 0), colors.HexColor("#dfe6f3")),
                ("VALIGN", (0, 0), (-1, -1), "TOP"),
                ("LEFTPADDING", (0, 0), (-1, -1), 2),
                ("RIGHTPADDING", (0, 0), (-1, -1), 2),
            ]
        )
    )
    out = [PdfParagraph(escape(block.caption), styles["caption"])] if block.caption else []
    return [*out, table, Spacer(1, 4 * mm)]


class _DeflatedImage(pdfdoc.PDFObject):
    """A PDF image XObject of an RGB PNG's deflated rows: Flate with PNG predictors reads them as they are."""

    def __init__(self, pixels: DeflatedRgb):
        self.pixels = pixels

    def format(self, document):
        stream = pdfdoc.PDFStream(content=self.pixels.data)
        stream.dictionary.dict.update(
            {
                "Type": pdfdoc.PDFName("XObject"),
                "Subtype": pdfdoc.PDFName("Image"),
                "Width": self.pixels.width,
                "Height": self.pixels.height,
                "BitsPerComponent": 8,
                "ColorSpace": pdfdoc.PDFName("DeviceRGB"),
                "Filter": pdfdoc.PDFName("FlateDecode"),  # one filter: DecodeParms a dictionary, not an array
                "DecodeParms": pdfdoc.PDFDictionary(
                    {"Predictor": 15, "Colors": 3, "BitsPerComponent": 8, "Columns": self.pixels.width}
                ),
            }
        )
        return stream.format(document)


class _Png(Flowable):
    """A PNG at ``width`` x ``height`` points, its deflated pixels embedded as they are: reportlab's own images
    decode a PNG and deflate its pixels again (a third of a report's PDF time). Registered as
    ``Canvas.drawImage`` registers an image (reportlab 4-5), which offers no way to pass compressed pixels."""

    def __init__(self, pixels: DeflatedRgb, png: bytes, width: float, height: float):
        super().__init__()
        self.pixels, self.name = pixels, hashlib.md5(png).hexdigest()
        self.width, self.height = width, height
        self.hAlign = "CENTER"  # as reportlab's Image

    def wrap(self, available_width, available_height):
        return self.width, self.height

    def draw(self):
        canvas, document = self.canv, self.canv._doc
        reference = document.getXObjectName(self.name)
        if reference not in document.idToObject:
            document.Reference(_DeflatedImage(self.pixels), reference)
        canvas._currentPageHasImages = 1
        canvas.saveState()
        canvas.scale(self.width, self.height)
        canvas._code.append(f"/{reference} Do")
        canvas.restoreState()
        canvas._formsinuse.append(self.name)


def _image(png: bytes, width: float, height: float) -> Flowable:
    """``png`` at ``width`` x ``height`` points: its pixels as they are (:class:`_Png`) when it is what the report
    writes (8-bit RGB), else through reportlab's own image."""
    pixels = deflated_rgb(png)
    if pixels is None:
        return Image(io.BytesIO(png), width=width, height=height)
    return _Png(pixels, png, width, height)


def _figure(block: Figure, styles, width: float) -> list:
    figure_width, figure_height = block.plot.figure.get_size_inches()
    height = min(width * figure_height / figure_width, 200 * mm)
    image = _image(png_bytes(block.plot), height * figure_width / figure_height, height)
    return [KeepTogether([image, PdfParagraph(escape(block.plot.caption), styles["caption"]), Spacer(1, 4 * mm)])]


def render_pdf(document: Document) -> bytes:
    """The PDF bytes of ``document``."""
    _register_fonts()
    styles = _styles()
    buffer = io.BytesIO()
    frame = SimpleDocTemplate(
        buffer,
        pagesize=A4,
        leftMargin=15 * mm,
        rightMargin=15 * mm,
        topMargin=15 * mm,
        bottomMargin=18 * mm,
        title=document.title,
        author="bench",
        subject=document.subtitle,
    )
    width = frame.width
    story = [
        PdfParagraph(escape(document.title), styles["title"]),
        PdfParagraph(escape(document.subtitle), styles["subtitle"]),
        Spacer(1, 4 * mm),
    ]
    for section in document.sections:
        story.append(PdfParagraph(escape(section.title), styles["h2"]))
        for block in section.blocks:
            if isinstance(block, Paragraph):
                story.append(PdfParagraph(escape(block.text), styles["body"]))
                story.append(Spacer(1, 2 * mm))
            elif isinstance(block, Table):
                story.extend(_table(block, styles, width))
            elif isinstance(block, Figure):
                story.extend(_figure(block, styles, width))
    canvas_class = type(
        "ReportCanvas", (_NumberedCanvas,), {"footer": document.subtitle, "banner": document.meta.get("banner") or ""}
    )
    frame.build(story, canvasmaker=canvas_class)
    return buffer.getvalue()


def write_pdf(document: Document, path: str | Path) -> Path:
    path = Path(path)
    path.write_bytes(render_pdf(document))
    return path
