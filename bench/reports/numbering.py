"""Report numbers: one per generated document, never shared by two documents that say different things.

A number reads ``BR-<run>-<content hash>-<issue>`` (a comparison ``BC-<run A>-<run B>-...``, a trend
``BT-<first run>-...``): the first 8 hex digits of the SHA-256 of every printed string of the document (the
generation time left out, so the same content hashes the same), and the issue counter of that content in the
output folder's ledger (:data:`LEDGER`: one line per issued number), so a report re-issued with the same content
gets ``-2``, ``-3`` ... and a report with another verdict, rule or identity gets another hash.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path

from bench.reports.language import map_text

__all__ = ["LEDGER", "content_hash", "numbered"]

#: The output folder's list of issued numbers (number, file stem, UTC), one per line, tab-separated.
LEDGER = "report-numbers.tsv"
_GENERATED = "Generated (UTC)"


def content_hash(document) -> str:
    """SHA-256 (hex) of every printed string of ``document`` except the generation time, in reading order."""
    from bench.reports.document import Figure, Paragraph, Table

    parts = [document.title, document.subtitle]
    for section in document.sections:
        parts.append(section.title)
        for block in section.blocks:
            if isinstance(block, Paragraph):
                parts.append(block.text)
            elif isinstance(block, Table):
                parts.extend([block.caption, *block.header])
                parts.extend(c for row in block.rows if not (row and row[0] == _GENERATED) for c in row)
            elif isinstance(block, Figure):
                parts.append(block.plot.caption)
    return hashlib.sha256("\x1f".join(parts).encode()).hexdigest()


def _prefix(stem: str) -> str:
    """``report_run7`` -> ``BR-00007``, ``compare_run1_run2`` -> ``BC-00001-00002``, ``trend_run1_...`` ->
    ``BT-00001``."""
    runs = [int(part[3:]) for part in stem.split("_") if part.startswith("run") and part[3:].isdigit()]
    kind = {"report": "BR", "compare": "BC", "trend": "BT"}.get(stem.split("_", 1)[0], "BR")
    shown = runs if kind != "BT" else runs[:1]
    return "-".join([kind, *(f"{r:05d}" for r in shown)])


def numbered(document, out: Path, stem: str):
    """``document`` with its unique number (module doc) in place of its provisional ``meta["report_id"]`` (and at
    the head of the subtitle when the provisional id is not printed), the number recorded in ``out``'s ledger."""
    digest = content_hash(document)[:8]
    base = f"{_prefix(stem)}-{digest}"
    ledger = Path(out) / LEDGER
    issued = ledger.read_text(encoding="utf-8").splitlines() if ledger.exists() else []
    issue = 1 + sum(line.split("\t", 1)[0].rsplit("-", 1)[0] == base for line in issued)
    number = f"{base}-{issue}"
    with ledger.open("a", encoding="utf-8") as handle:
        handle.write(f"{number}\t{stem}\t{datetime.now(UTC).isoformat(timespec='seconds')}\n")
    provisional = str(document.meta.get("report_id") or "")
    if provisional and provisional in document.subtitle:
        document = map_text(document, lambda text: text.replace(provisional, number))
    else:
        document = replace(
            document, subtitle=f"Report {number}" + (f"; {document.subtitle}" if document.subtitle else "")
        )
    return replace(document, meta={**document.meta, "report_id": number})
