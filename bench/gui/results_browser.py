"""The results browser: the runs in the store with their status, and what can be done with them.

The list is :meth:`bench.store.Store.runs` (the same rows as ``bench runs``), re-read whenever the store's files
change (runs made from the CLI included; :data:`POLL_MS`). "Report" writes the run's report with
:func:`bench.reports.write_report` and "Compare" two runs with :func:`bench.reports.write_comparison` (the
functions behind ``bench report``), then opens the HTML by its absolute file URL; "Resume" continues an unfinished
run with the runner's ``resume_run`` through the campaign panel; "Export CSV" writes the tidy table of
``bench export`` (same default sample kind). Store scans, reports, comparisons and exports run in background
tasks (:mod:`bench.gui.tasks`); each ends with a result or an error dialog, never a frozen window.
"""

from __future__ import annotations

import os
from pathlib import Path

from PySide6.QtCore import QTimer, QUrl, Signal
from PySide6.QtGui import QDesktopServices
from PySide6.QtWidgets import (
    QAbstractItemView,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QMessageBox,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from bench.gui.messages import show_message
from bench.gui.offload import in_worker_process, write_comparison_html, write_report_html
from bench.gui.tasks import Task, run_in_background
from bench.store import RunRecord, Store, export_run
from bench.store.ownership import owner_of

__all__ = ["COLUMNS", "POLL_MS", "ResultsBrowser", "file_url"]

#: Columns of the run table.
COLUMNS = ("id", "protocol", "robot", "campaign", "status", "samples", "started (UTC)", "reason")
#: How often the store's files are looked at for changes (one ``stat`` each, microseconds), ms.
POLL_MS = 1000


def file_url(path: str | Path) -> QUrl:
    """The absolute ``file://`` URL of ``path`` (a relative URL is not opened by desktop handlers)."""
    return QUrl.fromLocalFile(str(Path(path).resolve()))


def _export(store_path: str, run_id: int, report_dir: Path) -> Path:
    """``bench export RUN_ID`` into ``report_dir``: the tidy table of the run's default sample kind."""
    from bench.store import default_kind  # one home for bench export's default kind

    report_dir.mkdir(parents=True, exist_ok=True)
    with Store(store_path, read_only=True) as store:
        kind = default_kind(store, run_id)
        name = f"run-{run_id}.csv" if kind == "pose" else f"run-{run_id}-{kind}.csv"
        return export_run(store, run_id, report_dir / name, kind=kind)


class ResultsBrowser(QGroupBox):
    """Runs of the store at ``store_path``; ``resume_requested(run_id)`` asks the window to resume one.

    Attributes
    ----------
    last_dialog : QMessageBox or None
        The latest result or error dialog (non-modal: the window, and its emergency stop, stay usable).
    """

    resume_requested = Signal(int)
    message = Signal(str)
    refreshed = Signal(list)  #: the runs as last read from the store

    def __init__(
        self, store_path: str, report_dir: str | Path, parent: QWidget | None = None, *, open_files: bool = True
    ) -> None:
        super().__init__("Results", parent)
        self.store_path = store_path
        self.report_dir = Path(report_dir)
        self.open_files = open_files
        self.records: list[RunRecord] = []
        self.last_dialog: QMessageBox | None = None
        self._scan: Task | None = None
        self._rescan = False
        self._stamp: tuple = ()
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setObjectName("runTable")
        self.table.setHorizontalHeaderLabels(COLUMNS)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.verticalHeader().setVisible(False)
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        buttons = QHBoxLayout()
        self.buttons: dict[str, QPushButton] = {}
        for text, slot in (
            ("Refresh", self.refresh),
            ("Report", self.open_report),
            ("Compare 2", self.compare),
            ("Resume", self._resume),
            ("Export CSV", self.export_csv),
        ):
            button = QPushButton(text)
            button.setObjectName(f"results{text.split()[0]}")
            button.clicked.connect(lambda _=False, s=slot: s())
            buttons.addWidget(button)
            self.buttons[text.split()[0].lower()] = button
        self.busy = QLabel("")
        self.busy.setObjectName("resultsBusy")
        buttons.addWidget(self.busy, 1)
        layout = QVBoxLayout(self)
        layout.addWidget(self.table)
        layout.addLayout(buttons)
        self._poll = QTimer(self)
        self._poll.timeout.connect(self._poll_store)
        self._poll.start(POLL_MS)
        self.refresh()

    # ---- the run list ----------------------------------------------------------------------------------------

    def _store_stamp(self) -> tuple:
        stamp = []
        for suffix in ("", "-wal"):
            try:
                info = os.stat(self.store_path + suffix)
            except OSError:
                stamp.append(None)
            else:
                stamp.append((info.st_mtime_ns, info.st_size))
        # a run whose owner dies changes no file: its owner's liveness is part of the stamp (a lock probe, us)
        stamp += [
            (r.id, getattr(owner_of(self.store_path, r.id), "alive", False))
            for r in getattr(self, "records", [])
            if r.status == "running"
        ]
        return tuple(stamp)

    def _poll_store(self) -> None:
        stamp = self._store_stamp()
        if stamp != self._stamp:
            self.refresh()

    def stop_watching(self) -> None:
        """No more looks at the store (the window closes)."""
        self._poll.stop()

    def refresh(self) -> Task | None:
        """Read the runs again from the store, in the background (its own connection); the table follows."""
        if self._scan is not None:  # one scan at a time; the latest change is read after it
            self._rescan = True
            return self._scan
        self._stamp = self._store_stamp()
        path = self.store_path

        def scan() -> list[RunRecord]:
            if not Path(path).is_file():  # no run yet: an empty list, and no file made where none was asked for
                return []
            with Store(path, read_only=True) as store:
                return store.runs()

        self._scan = run_in_background(
            "reading the store",
            scan,
            self,
            on_done=self._show_records,
            on_failed=self.message.emit,
            on_ended=self._scan_ended,
        )
        return self._scan

    def _scan_ended(self) -> None:
        self._scan = None
        if self._rescan:
            self._rescan = False
            self.refresh()

    def _show_records(self, records: list[RunRecord]) -> None:
        selected = self.selected_run_ids()
        self.records = records
        self.table.setRowCount(len(records))
        for row, record in enumerate(reversed(records)):  # newest first
            cells = (
                record.id,
                f"{record.protocol_name} v{record.protocol_version}",
                record.robot,
                record.campaign or "",
                record.status,
                record.n_samples,
                record.started_utc[:19],
                record.reason or "",
            )
            for column, value in enumerate(cells):
                self.table.setItem(row, column, QTableWidgetItem(str(value)))
        if selected:
            self.select_runs(selected)
        self.refreshed.emit(records)

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

    # ---- reports, comparisons, exports -----------------------------------------------------------------------

    def open_report(self) -> Task | None:
        """Write the selected run's report (HTML and PDF) in the background, then open the HTML."""
        ids = self.selected_run_ids()
        if len(ids) != 1:
            self.message.emit("Report: select one run")
            return None
        store_path, report_dir = str(self.store_path), self.report_dir
        return self._background(
            f"report of run {ids[0]}",
            lambda: in_worker_process(write_report_html, store_path, ids[0], report_dir),
            show=True,
        )

    def compare(self) -> Task | None:
        """Write the comparison of the two selected runs in the background, then open it."""
        ids = self.selected_run_ids()
        if len(ids) != 2:
            self.message.emit("Compare: select exactly two runs")
            return None
        store_path, report_dir = str(self.store_path), self.report_dir

        def write() -> Path:
            return in_worker_process(write_comparison_html, store_path, ids[0], ids[1], report_dir)

        return self._background(f"comparison of runs {ids[0]} and {ids[1]}", write, show=True)

    def export_csv(self) -> Task | None:
        """Write the selected run's tidy table (``bench export``'s default kind) next to the reports."""
        ids = self.selected_run_ids()
        if len(ids) != 1:
            self.message.emit("Export: select one run")
            return None
        store_path, report_dir = self.store_path, self.report_dir
        return self._background(f"export of run {ids[0]}", lambda: _export(store_path, ids[0], report_dir), show=False)

    def _background(self, what: str, write, *, show: bool) -> Task:
        self.busy.setText(f"writing the {what}...")
        task = run_in_background(
            what,
            write,
            self,
            on_done=lambda path: self._written(what, Path(path).resolve(), show),
            on_failed=lambda text: self._task_failed(what, text),
        )
        return task

    def _written(self, what: str, path: Path, show: bool) -> None:
        self.busy.setText("")
        self.message.emit(f"wrote {path}")
        self._dialog(QMessageBox.Icon.Information, f"{what[0].upper()}{what[1:]} written", str(path))
        if show and self.open_files:
            QDesktopServices.openUrl(file_url(path))

    def _task_failed(self, what: str, text: str) -> None:
        self.busy.setText("")
        self.message.emit(text)
        self._dialog(QMessageBox.Icon.Warning, f"The {what} failed", text)

    def _dialog(self, icon: QMessageBox.Icon, title: str, text: str) -> None:
        self.last_dialog = show_message(self, icon, title, text, name="resultsDialog")

    def _resume(self) -> None:
        ids = self.selected_run_ids()
        if len(ids) != 1:
            self.message.emit("Resume: select one run")
            return
        self.resume_requested.emit(ids[0])
