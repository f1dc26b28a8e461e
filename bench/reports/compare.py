"""Comparisons of two runs for every layout, and the run histories side by side.

Pose runs get :func:`bench.reports.pose_document.comparison_document` (paired AP/RP per pose with the difference B − A);
runs of a layout of their own (actuator, payload ladder, laser grid, positioning, stabilisation; both runs of the
same protocol) get :func:`layout_comparison`: identification, the configuration keys that differ, the histories,
the deviation tables side by side, then each run's own results section (the tables its single report prints), A
then B. Every comparison carries :func:`history_section`, so two runs with the same configuration but a paused,
aborted or resumed history do not read as "identical".
"""

from __future__ import annotations

from dataclasses import replace
from itertools import zip_longest

from bench.reports.content import ReportBase
from bench.reports.differences import NO_DIFFERENCE, configuration_differences
from bench.reports.document import Document, Paragraph, RawData, Section, Table, _raw
from bench.reports.summary import HistoryEvent

__all__ = ["comparison_head", "history_section", "layout_comparison", "paired_deviations", "with_histories"]


def _history_text(history: tuple[HistoryEvent, ...]) -> list[str]:
    return [f"{event.time_utc}: {event.event}" for event in history]


def history_section(first: ReportBase, second: ReportBase, histories) -> Section:
    """The two runs' histories (start, interruptions, end), event by event, with a line saying whether they differ."""
    a, b = (_history_text(h) for h in histories)
    rows = tuple((str(i + 1), x or "—", y or "—") for i, (x, y) in enumerate(zip_longest(a, b)))
    kinds = [tuple(e.event.split(":")[0] for e in h[1:]) for h in histories]
    same = kinds[0] == kinds[1]
    text = (
        "Both runs ran the same way (same sequence of events)."
        if same
        else "The runs differ in their history (interruptions or end status): their results are not comparable "
        "as like for like."
    )
    return Section(
        "Run histories",
        (Paragraph(text), Table("history", ("#", f"A: run {first.run.id}", f"B: run {second.run.id}"), rows)),
    )


def with_histories(document: Document, first: ReportBase, second: ReportBase, histories) -> Document:
    """``document`` (a comparison) with :func:`history_section` after its conditions, and its "same configuration"
    line qualified when the histories differ."""
    section = history_section(first, second, histories)
    sections = list(document.sections)
    sections.insert(min(2, len(sections)), section)
    if "differ in their history" in section.blocks[0].text:
        sections = [
            replace(
                s,
                blocks=tuple(
                    replace(
                        b,
                        rows=tuple(
                            tuple(
                                f"{NO_DIFFERENCE}, different history (see Run histories)" if c == NO_DIFFERENCE else c
                                for c in row
                            )
                            for row in b.rows
                        ),
                    )
                    if isinstance(b, Table)
                    else b
                    for b in s.blocks
                ),
            )
            for s in sections
        ]
    return replace(document, sections=tuple(sections))


def _results(document: Document, prefix: str) -> tuple:
    for section in document.sections:
        if section.title.startswith("6."):
            return tuple(replace(b, ident=f"{prefix}-{b.ident}") if isinstance(b, Table) else b for b in section.blocks)
    return (Paragraph("no results section"),)


def comparison_head(first: ReportBase, second: ReportBase) -> tuple[Section, Section]:
    """The first two sections of every comparison: both runs identified, and every configuration, setting and
    calibration in force that differs (:func:`bench.reports.differences.configuration_differences`)."""
    a, b = first.run, second.run
    ident = (
        ("Configuration ID", first.report_id, second.report_id),
        ("Protocol", a.protocol_name, b.protocol_name),
        ("Robot", a.robot, b.robot),
        ("Status", a.status, b.status),
        ("Started (UTC)", a.started_utc, b.started_utc),
        ("Git SHA", a.git_sha, b.git_sha),
        ("Configuration SHA-256", first.config_sha256[:16], second.config_sha256[:16]),
        ("Calibration ids", str(list(a.calibration_ids)), str(list(b.calibration_ids))),
    )
    differ = configuration_differences(first, second) or (("—", NO_DIFFERENCE, ""),)
    return (
        Section("1. Identification", (Table("identification", ("Item", f"A: run {a.id}", f"B: run {b.id}"), ident),)),
        Section(
            "2. Conditions that differ",
            (
                Table(
                    "conditions", ("Parameter", "A", "B"), differ, "Configuration, settings and calibrations in force"
                ),
            ),
        ),
    )


def paired_deviations(first: ReportBase, second: ReportBase) -> tuple[tuple[str, str, str, str], ...]:
    """The two runs' deviations rows side by side: clause, topic, A's status and what was done, B's."""
    return tuple(
        (d.clause, d.topic, f"{d.status}: {d.done}", f"{e.status}: {e.done}")
        for d, e in zip(first.deviations, second.deviations)
    )


def layout_comparison(
    first: ReportBase, second: ReportBase, first_document: Document, second_document: Document, raw: list[RawData]
) -> Document:
    """Two runs of the same own-layout protocol side by side (see module doc)."""
    a, b = first.run, second.run
    return Document(
        title=f"Comparison of run {a.id} (A) and run {b.id} (B): {first.title}",
        subtitle=f"Runs {a.id} (A) and {b.id} (B)",
        sections=(
            *comparison_head(first, second),
            Section(
                f"3. Deviations from {first.reference}",
                (Table("deviations", ("Clause", "Topic", "A", "B"), paired_deviations(first, second)),),
            ),
            Section(f"4. Results of A (run {a.id})", _results(first_document, "a")),
            Section(f"5. Results of B (run {b.id})", _results(second_document, "b")),
            _raw(raw, first.notes + second.notes, "see each run's own report"),
        ),
        meta={"report_id": f"{first.report_id}_vs_{second.report_id}"},
    )
