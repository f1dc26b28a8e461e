"""Customer language: what a report prints contains no path of the bench PC, no module name of the software and no
reference to the project's internal notes; it cites the standard's clauses and the published documents instead.

:func:`customer_text` rewrites one string, :func:`customer_document` every string of a document (paragraphs, table
headers and cells, figure captions). The layouts keep their precise internal references in their source (for the
developers); the printed report gets the published names:

- ``000 §8.4`` (the project's short name of the pkm5 dissertation) -> ``pkm5 dissertation §8.4``;
- the project's reference notes (``iso9283.md §7.1``, ``delta4-lasergrid.md §6.5``, ``sensors.md``,
  ``docs/campaigns.md``) -> the published document they distil (ISO 230-2, the delta-robot dissertation), or
  nothing where the note only records a project choice;
- ``bench.metrology.instrument_rp_floor`` and other module names -> what they compute;
- absolute paths (``/tmp/bench-sim-x/mouse_xy.fifo``, ``/tmp/x/bench.db``) -> their file name (``bench.db``),
  also in the verbatim recomputing commands (which otherwise keep their module names).
"""

from __future__ import annotations

import re
from dataclasses import replace

__all__ = ["INTERNAL_PATTERNS", "customer_document", "customer_text", "local_paths", "map_text"]

PKM5_DISSERTATION = "pkm5 dissertation"
DELTA_DISSERTATION = "delta-robot dissertation"

#: Sections of the project's ISO 9283 note that stand for a published method, by section prefix.
_ISO_NOTE = (
    ("§7.1", "ISO 230-2"),
    ("§7.4", "Groover's actuator accuracy"),
    ("§12", "project definition"),
    ("§4.2", "ISO 9283:1998 6.7"),
    ("§6.6", "ISO 9283:1998 7.2"),
)

_MODULES = {
    "instrument_rp_floor": "RP of a perfect robot seen through the instrument",
    "leg_error_summary": "per-leg error statistics",
    "payload_compliance": "least-squares compliance",
    "payload_shift": "payload error PE(m)",
}

#: What must never reach a customer (a test checks every printed report against these).
INTERNAL_PATTERNS = (
    re.compile(r"\b[\w-]+\.md\b"),
    re.compile(r"\bdocs/"),
    re.compile(r"\bbench\.\w"),
    re.compile(r"(?<![\w.])/(?:tmp|dev|home|work|var|usr)/"),
    re.compile(r"\(motion/\)"),
)


def _iso_note(match: re.Match) -> str:
    section = match.group(1) or ""
    for prefix, name in _ISO_NOTE:
        if section.startswith(prefix):
            return name
    return ""


def local_paths(text: str) -> str:
    """Absolute paths of the bench PC reduced to their file name (``/tmp/x/bench.db`` -> ``bench.db``)."""
    return re.sub(
        r"(?<![\w.])/(?:tmp|dev|home|work|var|usr|root|mnt|srv)/[^\s),;'\"]*",
        lambda m: m.group(0).rstrip("/").rsplit("/", 1)[-1],
        text,
    )


def customer_text(text: str) -> str:
    """``text`` with internal references replaced by published ones and local paths removed (see module doc)."""
    text = re.sub(r"\biso9283\.md(?: (§[\d.]+))?", _iso_note, text)
    text = re.sub(r"\b(?:delta4-lasergrid|prus3)\.md(?: §[\d.]+)?", DELTA_DISSERTATION, text)
    text = re.sub(r"\bpkm5\.md(?: §[\d.]+)?", PKM5_DISSERTATION, text)
    text = re.sub(r"\bdocs/[\w./-]+(?: §[\d.]+)?", "", text)
    text = re.sub(r"\b[\w-]+\.md(?: §[\d.]+)?", "", text)
    text = re.sub(r"\b000(?= (?:§|Table|Eqs?\.|App))", PKM5_DISSERTATION, text)
    text = re.sub(r"\bbench\.metrology(?:\.\w+)*\.(\w+)", lambda m: _MODULES.get(m.group(1), "the analysis"), text)
    text = re.sub(r"\bbench\.metrology\b", "the analysis", text)
    text = local_paths(text)
    text = text.replace("(motion/)", "(kinematic model)")
    # tidy what a removed reference leaves behind: "( , x)", "(x, )", "()", doubled spaces
    text = re.sub(r"\(\s*[,;]\s*", "(", text)
    text = re.sub(r"\s*[,;]\s*\)", ")", text)
    text = re.sub(r"\s*\(\s*(?:see|cf\.)?\s*\)", "", text)
    text = re.sub(r"  +", " ", text)
    return text


def map_text(document, text, verbatim=None):
    """``document`` with ``text`` applied to every printed string (title, subtitle, section titles, paragraphs,
    table headers, cells and captions, figure captions); verbatim paragraphs get ``verbatim`` (default ``text``)."""
    from bench.reports.document import Figure, Paragraph, Section, Table
    from bench.reports.plots import Plot

    verbatim = verbatim or text

    def block(item):
        if isinstance(item, Paragraph):
            return replace(item, text=verbatim(item.text) if item.verbatim else text(item.text))
        if isinstance(item, Table):
            return replace(
                item,
                header=tuple(text(c) for c in item.header),
                rows=tuple(tuple(text(c) for c in row) for row in item.rows),
                caption=text(item.caption),
            )
        if isinstance(item, Figure):
            return Figure(Plot(text(item.plot.caption), item.plot.figure))
        return item

    sections = tuple(Section(text(s.title), tuple(block(b) for b in s.blocks)) for s in document.sections)
    return replace(document, title=text(document.title), subtitle=text(document.subtitle), sections=sections)


def customer_document(document):
    """``document`` with :func:`customer_text` applied to every printed string (a verbatim command keeps its module
    names and loses only local paths)."""
    return map_text(document, customer_text, local_paths)
