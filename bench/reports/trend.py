"""A trend over N pose runs (drift across days): ``bench report RUN --trend RUN ...``.

Per run, in the order of their start times: the headline of its report (per velocity and load: worst and mean AP_P
and RP_l with U, :func:`bench.reports.summary.headline_rows`), its status and interruptions; and one figure of the
worst AP_P and RP_l of each run with their U as error bars, against the run's start date. Every number is the
single report's number (same collector), rounded by its uncertainty.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure as MplFigure

from bench.reports.content import RunReport, axes_statement, check_same_axes
from bench.reports.document import Document, Figure, Paragraph, RawData, Section, Table, _raw
from bench.reports.plots import Plot, nonnegative_yerr
from bench.reports.summary import HistoryEvent, headline_rows

__all__ = ["trend_document", "trend_plot"]


def _worst(report: RunReport, attribute: str):
    return max((getattr(p, attribute) for p in report.poses), key=lambda m: m.value)


def trend_plot(reports: Sequence[RunReport]) -> Plot:
    """Worst AP_P and worst RP_l of each run (error bars: U) against the run, labelled by id and start date."""
    figure = MplFigure(figsize=(7.0, 2.8), layout="constrained")
    positions = np.arange(len(reports))
    labels = [f"run {r.run.id}\n{r.run.started_utc[:10]}" for r in reports]
    for index, (name, attribute) in enumerate((("worst AP_P", "ap_u"), ("worst RP_l", "rp_u"))):
        axes = figure.add_subplot(1, 2, index + 1)
        worst = [_worst(r, attribute) for r in reports]
        values = [m.value for m in worst]
        axes.errorbar(
            positions,
            values,
            yerr=nonnegative_yerr(values, [m.expanded_uncertainty for m in worst]),
            marker="o",
            capsize=3,
        )
        axes.set_xticks(positions, labels)
        axes.set_ylabel(f"{name} (mm)")
        axes.set_ylim(bottom=0)
    return Plot(
        f"Worst AP_P and worst RP_l of each run, in the order of their start (error bars: U, k = "
        f"{reports[0].coverage_factor:g}).",
        figure,
    )


def trend_document(
    reports: Sequence[RunReport], histories: Sequence[tuple[HistoryEvent, ...]], raw: list[RawData]
) -> Document:
    """The trend report of ``reports`` (already in start order) with their histories and raw data; runs measured
    on different axes are refused (:func:`bench.reports.content.check_same_axes`)."""
    check_same_axes(reports, "--trend")
    axes = axes_statement(reports[0])
    rows = []
    for report in reports:
        for row in headline_rows(report.poses):
            rows.append((str(report.run.id), report.run.started_utc[:10], *row))
    header = (
        "Run",
        "Date",
        "Conditions",
        "Poses",
        "Worst AP_P ± U (mm)",
        "Mean AP_P ± U (mm)",
        "Worst RP_l ± U (mm)",
        "Mean RP_l ± U (mm)",
    )
    history_rows = tuple(
        (str(r.run.id), r.run.status + (f": {r.run.reason}" if r.run.reason else ""), str(len(h) - 2))
        for r, h in zip(reports, histories)
    )
    ids = ", ".join(str(r.run.id) for r in reports)
    return Document(
        title=f"Trend over runs {ids}",
        subtitle=f"Runs {ids}",
        sections=(
            Section(
                "1. Results per run",
                (
                    Paragraph(
                        "Each run's headline as its own report gives it; runs in the order they started."
                        + (f" {axes}." if axes else "")
                    ),
                    Table(
                        "trend",
                        header,
                        tuple(rows),
                        f"Per run, velocity and load (U: k = {reports[0].coverage_factor:g})",
                    ),
                ),
            ),
            Section("2. Trend", (Figure(trend_plot(reports)),)),
            Section("3. Run histories", (Table("history", ("Run", "End status", "Interruptions"), history_rows),)),
            _raw(raw, tuple(n for r in reports for n in r.notes), "see each run's own report"),
        ),
        meta={"report_id": "_".join(r.report_id for r in reports)},
    )
