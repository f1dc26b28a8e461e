"""The results browser: the runs in the store with their status, and what can be done with them.

The list is :meth:`bench.store.Store.runs` (the same rows as ``bench runs``). "Report" writes the run's report with
:func:`bench.reports.write_report` and "Compare" two runs with :func:`bench.reports.write_comparison` (the
functions behind ``bench report``), then opens the HTML; "Resume" continues an unfinished run with the runner's
``resume_run`` through the campaign panel; "Export CSV" writes the tidy table of ``bench export``.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QUrl, Signal
from PySide6.QtGui import QDesktopServices
from PySide6.QtWidgets import (
    QAbstractItemView,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from bench.errors import BenchError
from bench.store import RunRecord, Store, export_run

__all__ = ["COLUMNS", "ResultsBrowser"]

#: Columns of the run table.
COLUMNS = ("id", "protocol", "robot", "campaign", "status", "samples", "started (UTC)", "reason")


class ResultsBrowser(QGroupBox):
    """Runs of the store at ``store_path``; ``resume_requested(run_id)`` asks the window to resume one."""

    resume_requested = Signal(int)
    message = Signal(str)

    def __init__(self, store_path: str, report_dir: str | Path, parent: QWidget | None = None,
                 *, open_files: bool = True) -> None:
        super().__init__("Results", parent)
        self.store_path = store_path
        self.report_dir = Path(report_dir)
        self.open_files = open_files
        self.records: list[RunRecord] = []
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setObjectName("runTable")
        self.table.setHorizontalHeaderLabels(COLUMNS)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.verticalHeader().setVisible(False)
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        buttons = QHBoxLayout()
        for text, slot in (("Refresh", self.refresh), ("Report", self.open_report), ("Compare 2", self.compare),
                           ("Resume", self._resume), ("Export CSV", self.export_csv)):
            button = QPushButton(text)
            button.setObjectName(f"results{text.split()[0]}")
            button.clicked.connect(lambda _=False, s=slot: s())
            buttons.addWidget(button)
        buttons.addStretch(1)
        layout = QVBoxLayout(self)
        layout.addWidget(self.table)
        layout.addLayout(buttons)
        self.refresh()

    def refresh(self) -> list[RunRecord]:
        """Read the runs again from the store (its own connection, in the GUI thread)."""
        with Store(self.store_path) as store:
            self.records = store.runs()
        self.table.setRowCount(len(self.records))
        for row, record in enumerate(reversed(self.records)):  # newest first
            cells = (record.id, f"{record.protocol_name} v{record.protocol_version}", record.robot,
                     record.campaign or "", record.status, record.n_samples, record.started_utc[:19],
                     record.reason or "")
            for column, value in enumerate(cells):
                self.table.setItem(row, column, QTableWidgetItem(str(value)))
        return self.records

    def selected_run_ids(self) -> list[int]:
        rows = sorted({index.row() for index in self.table.selectionModel().selectedRows()})
        return sorted(int(self.table.item(row, 0).text()) for row in rows)  # oldest first: "before" vs "after"

    def select_runs(self, run_ids: list[int]) -> None:
        self.table.clearSelection()
        mode = self.table.selectionMode()
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.MultiSelection)
        for row in range(self.table.rowCount()):
            if int(self.table.item(row, 0).text()) in run_ids:
                self.table.selectRow(row)
        self.table.setSelectionMode(mode)

    def open_report(self) -> Path | None:
        """Write the selected run's report (HTML and PDF) and open the HTML; returns its path."""
        ids = self.selected_run_ids()
        if len(ids) != 1:
            self.message.emit("Report: select one run")
            return None
        from bench.reports import write_report

        return self._open(lambda: write_report(self.store_path, ids[0], self.report_dir).html)

    def compare(self) -> Path | None:
        """Write the comparison of the two selected runs and open it; returns its path."""
        ids = self.selected_run_ids()
        if len(ids) != 2:
            self.message.emit("Compare: select exactly two runs")
            return None
        from bench.reports import write_comparison

        return self._open(lambda: write_comparison(self.store_path, ids[0], ids[1], self.report_dir).html)

    def export_csv(self) -> Path | None:
        """Write the selected run's tidy table next to the reports."""
        ids = self.selected_run_ids()
        if len(ids) != 1:
            self.message.emit("Export: select one run")
            return None
        self.report_dir.mkdir(parents=True, exist_ok=True)

        def write() -> Path:
            with Store(self.store_path) as store:
                return export_run(store, ids[0], self.report_dir / f"run-{ids[0]}.csv")

        return self._open(write, show=False)

    def _open(self, write, *, show: bool = True) -> Path | None:
        try:
            path = write()
        except BenchError as exc:
            self.message.emit(str(exc))
            return None
        self.message.emit(f"wrote {path}")
        if show and self.open_files:
            QDesktopServices.openUrl(QUrl.fromLocalFile(str(path)))
        return path

    def _resume(self) -> None:
        ids = self.selected_run_ids()
        if len(ids) != 1:
            self.message.emit("Resume: select one run")
            return
        self.resume_requested.emit(ids[0])
