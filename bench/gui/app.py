"""The main window of ``bench gui``: robot panel, campaign panel, live view, results browser, log, and a software
emergency stop that is always visible and always reachable (button and F12, even while a calliper prompt is open).

The window wires the panels to the campaign worker's signals and adds no logic of its own: runs go through
bench's runner and store (:mod:`bench.gui.worker`), with the kinematic calibration chosen in the calibration panel
(:mod:`bench.gui.calibration_panel`), pre-flight through :mod:`bench.protocols`, statistics through
:mod:`bench.metrology`, reports through :mod:`bench.reports`.

The emergency stop is a latch (:class:`bench.gui.estop.EmergencyStop`): the button (on mouse-down) and F12 only set
it; its own thread takes it to the wire. F12 is caught by an application-wide event filter, so it acts in every window
of bench, a modal dialog of Qt's included (a ``QShortcut`` is blocked by one); the window itself opens no modal
dialog, so the button stays clickable. Closing the window during a run presses the emergency stop first (the robot
stops at once, the run ends aborted and resumable), then asks whether to close; the window never waits on its own
thread for a run to end.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtGui import QCloseEvent, QKeyEvent
from PySide6.QtWidgets import (
    QApplication,
    QLabel,
    QMainWindow,
    QMessageBox,
    QPlainTextEdit,
    QPushButton,
    QSplitter,
    QTabWidget,
    QToolBar,
    QVBoxLayout,
    QWidget,
)

from bench.gui.calibration_panel import CalibrationPanel
from bench.gui.calliper_dialog import CalliperDialog
from bench.gui.campaign_panel import CampaignPanel
from bench.gui.estop import HANDOFF_S, EmergencyStop
from bench.gui.live_view import LiveView
from bench.gui.messages import show_message
from bench.gui.offload import shutdown_worker_process
from bench.gui.results_browser import ResultsBrowser
from bench.gui.robot_panel import RobotPanel
from bench.gui.worker import CampaignWorker, RigSpec
from bench.protocols import Prompt, RunResult

__all__ = ["ESTOP_KEY", "MainWindow"]

#: The keyboard shortcut of the emergency stop, active in every window of the application.
ESTOP_KEY = Qt.Key.Key_F12
#: What the emergency stop button says it is (IEC 60204-1 stop categories; a hard-wired stop is the safety device).
ESTOP_TOOLTIP = (
    "Software emergency stop (stop category 1/2, IEC 60204-1), F12 from any window of bench: sends the "
    "robot's stop at once, withdraws a pending prompt, ends the run aborted (resumable). It is not a "
    "safety device: the hard-wired emergency stop of the cell is."
)

_log = logging.getLogger(__name__)

#: The question a close during a run asks, after the emergency stop went out.
CLOSE_QUESTION = (
    "The robot was stopped (software emergency stop) and the run ends aborted; every stored sample "
    "stays, and Resume continues it.\n\nClose the window?"
)


class _EstopKeyFilter(QObject):
    """F12 anywhere in the application, a modal dialog's window included, presses the emergency stop."""

    def __init__(self, press) -> None:
        super().__init__()
        self._press = press

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        if (
            event.type() in (QEvent.Type.KeyPress, QEvent.Type.ShortcutOverride)
            and isinstance(event, QKeyEvent)
            and event.key() == ESTOP_KEY
        ):
            if event.type() is QEvent.Type.KeyPress and not event.isAutoRepeat():
                self._press()
            return True  # consumed: never typed into a field, never a shortcut of a dialog
        return False


class MainWindow(QMainWindow):
    """The bench desktop window on the run store ``store_path``; reports go to ``report_dir``."""

    def __init__(
        self, store_path: str | Path = "bench.db", report_dir: str | Path = "reports", *, open_files: bool = True
    ) -> None:
        super().__init__()
        self.store_path = str(store_path)
        self.setWindowTitle(f"bench - {self.store_path}")
        self.calliper_dialog: CalliperDialog | None = None
        self.last_dialog: QMessageBox | None = None
        self.close_question: QMessageBox | None = None
        self._close_confirmed = False
        self.estop_latch = EmergencyStop()
        self.robot_panel = RobotPanel(estop=self.estop_latch)
        self.live_view = LiveView()
        self.results = ResultsBrowser(self.store_path, report_dir, open_files=open_files)
        self.calibration_panel = CalibrationPanel(
            self.store_path, self.results.selected_run_ids, robot=self.robot_panel.robot.currentText
        )
        self.campaign_panel = CampaignPanel(self.store_path, self.rig_spec, estop=self.estop_latch)
        self.log = QPlainTextEdit()
        self.log.setObjectName("log")
        self.log.setReadOnly(True)
        self.log.setMaximumBlockCount(2000)
        self._build_layout()
        self._build_toolbar()
        self.robot_panel.message.connect(self.say)
        self.robot_panel.robot.currentTextChanged.connect(self._robot_changed)
        self.campaign_panel.message.connect(self.say)
        self.campaign_panel.worker_started.connect(self._connect_worker)
        self.results.message.connect(self.say)
        self.results.refreshed.connect(lambda _: self.calibration_panel.refresh())
        self.calibration_panel.message.connect(self.say)
        self.results.resume_requested.connect(lambda run_id: self.campaign_panel.start([run_id]))
        self.resize(1400, 860)

    def _build_layout(self) -> None:
        tabs = QTabWidget()
        tabs.addTab(self.live_view, "Live view")
        tabs.addTab(self.results, "Results")
        self.tabs = tabs
        right = QSplitter(Qt.Orientation.Vertical)
        right.addWidget(tabs)
        right.addWidget(self.log)
        right.setSizes([640, 160])
        left = QWidget()
        column = QVBoxLayout(left)
        column.setContentsMargins(0, 0, 0, 0)
        column.addWidget(self.robot_panel, 1)
        column.addWidget(self.calibration_panel)
        main = QSplitter(Qt.Orientation.Horizontal)
        for widget in (left, self.campaign_panel, right):
            main.addWidget(widget)
        main.setSizes([300, 420, 680])
        self.setCentralWidget(main)

    def _build_toolbar(self) -> None:
        bar = QToolBar("Safety")
        bar.setMovable(False)
        self.estop = QPushButton("EMERGENCY STOP (software, F12)")
        self.estop.setObjectName("emergencyStop")
        self.estop.setToolTip(ESTOP_TOOLTIP)
        self.estop.setMinimumHeight(44)
        self.estop.setStyleSheet(
            "QPushButton {background: #c62828; color: white; font-weight: bold;"
            " font-size: 15px; padding: 6px 24px; border-radius: 4px}"
        )
        self.estop.pressed.connect(self.emergency_stop)  # on mouse-down: nothing more to wait for
        self.estop.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # never the target of a stray Space or Enter
        self._key_filter = _EstopKeyFilter(self.emergency_stop)
        QApplication.instance().installEventFilter(self._key_filter)
        self.reset_estop = QPushButton("Reset e-stop")
        self.reset_estop.setObjectName("resetEmergencyStop")
        self.reset_estop.setToolTip("After checking the robot: allow runs and jogs again (releases the robot's latch)")
        self.reset_estop.clicked.connect(self.reset_emergency_stop)
        self.reset_estop.setEnabled(False)
        bar.addWidget(self.estop)
        bar.addWidget(self.reset_estop)
        note = QLabel("  software stop (category 1/2): the hard-wired emergency stop of the cell is the safety device")
        note.setObjectName("estopNote")
        bar.addWidget(note)
        spacer = QWidget()
        bar.addWidget(spacer)
        self.addToolBar(Qt.ToolBarArea.TopToolBarArea, bar)

    # ---- actions -------------------------------------------------------------------------------------------

    def rig_spec(self, **options) -> RigSpec:
        """Where the window's runs happen: the robot panel's robot and connection, with the kinematic calibration
        chosen in the calibration panel."""
        return dataclasses.replace(
            self.robot_panel.rig_spec(**options), kinematic_calibration=self.calibration_panel.choice()
        )

    def say(self, text: str) -> None:
        """A line in the log panel (and the log)."""
        _log.info("%s", text)
        self.log.appendPlainText(text)

    def emergency_stop(self) -> None:
        """Press the emergency stop: the stop thread stops the campaign's robot (the run ends aborted, resumable, no
        clean-up moves) and the jogging robot; a pending calliper dialog closes (its prompt is withdrawn). The press
        comes first, before anything is drawn, and the stop thread goes first (up to HANDOFF_S)."""
        self.estop_latch.press(HANDOFF_S)
        self._close_calliper_dialog()
        self.robot_panel.show_latched()
        self.campaign_panel.refresh_buttons()
        self.reset_estop.setEnabled(self.campaign_panel.worker is None)
        self.say("EMERGENCY STOP (software)")

    def reset_emergency_stop(self) -> None:
        """The operator checked the robot: runs and jogs may start again."""
        if self.campaign_panel.worker is not None:
            self.say("reset e-stop: wait for the stopped run to end")
            return
        self.estop_latch.reset()
        self.reset_estop.setEnabled(False)
        self.robot_panel.release_stop()
        self.campaign_panel.refresh_buttons()
        self.say("emergency stop reset")

    def _close_calliper_dialog(self) -> None:
        """Close the dialog without its signals: the worker has already withdrawn the prompt."""
        if self.calliper_dialog is not None:
            self.calliper_dialog.withdraw()
            self.calliper_dialog = None

    def _robot_changed(self, robot: str) -> None:
        self.calibration_panel.refresh()  # the chooser lists this robot's calibrations
        path = self.campaign_panel.files.currentData()
        if path:
            self.campaign_panel.choose_file(path)

    def _connect_worker(self, worker: CampaignWorker) -> None:
        if self.robot_panel.mover is not None:  # one connection to the robot at a time
            self.say("disconnecting the jog connection for the campaign")
            self.robot_panel.disconnect_robot()
        self.robot_panel.setEnabled(False)
        worker.run_started.connect(self._run_started)
        worker.samples_loaded.connect(
            lambda run_id, started_s, samples: self.live_view.load(f"run {run_id}", started_s, samples)
        )
        worker.sample_stored.connect(lambda run_id, sample: self.live_view.add_sample(sample))
        worker.prompt_requested.connect(self.ask_reading)
        worker.run_finished.connect(self._run_finished)
        worker.failed.connect(self._job_failed)
        worker.finished.connect(self._worker_finished)
        self.tabs.setCurrentWidget(self.live_view)

    def _worker_finished(self) -> None:
        self.robot_panel.setEnabled(True)
        self.reset_estop.setEnabled(self.estop_latch.latched)
        if self._close_confirmed:
            self.close()

    def _run_started(self, run_id: int, total: int, done: int) -> None:
        self.say(f"run {run_id} started ({total - done} of {total} samples to take)")
        self.results.refresh()

    def _run_finished(self, result: RunResult) -> None:
        self.live_view.schedule_redraw()
        reason = f": {result.reason}" if result.reason else ""
        self.say(f"run {result.run_id} {result.exit_status} ({result.samples} samples){reason}")
        self.results.refresh()
        if result.exit_status != "completed" and not self.campaign_panel.ended_by_operator:
            self._show_dialog(
                QMessageBox.Icon.Warning,
                f"Run {result.run_id} {result.exit_status}",
                f"Run {result.run_id} ended {result.exit_status}{reason}.\n\n{result.samples} samples "
                f"are stored. To continue it: Resume in the Results tab, or\n"
                f"bench resume {result.run_id} --store {self.store_path}",
            )

    def _job_failed(self, text: str) -> None:
        self._show_dialog(QMessageBox.Icon.Warning, "The campaign could not start", text)

    def _show_dialog(self, icon: QMessageBox.Icon, title: str, text: str) -> QMessageBox:
        """A non-modal message: it never blocks the emergency stop."""
        self.last_dialog = show_message(self, icon, title, text, name="runDialog")
        return self.last_dialog

    def ask_reading(self, prompt: Prompt) -> CalliperDialog:
        """Show the calliper dialog for ``prompt``; its answer goes straight to the waiting run."""
        worker = self.campaign_panel.worker
        dialog = CalliperDialog(prompt, self, number=worker.reading_number if worker is not None else None)
        if worker is not None:
            dialog.reading_entered.connect(worker.answer)
            dialog.confirmed.connect(lambda: worker.answer(0.0))  # any value: a confirmation returns None
            dialog.cancelled.connect(lambda: worker.withdraw("cancelled in the calliper dialog"))
        dialog.reading_entered.connect(lambda value: self.say(f"{prompt.field} = {value:g} {prompt.unit}"))
        dialog.confirmed.connect(lambda: self.say(f"confirmed: {prompt.text}"))
        dialog.finished.connect(lambda _: setattr(self, "calliper_dialog", None))
        self.calliper_dialog = dialog
        dialog.show()  # non-modal: the emergency stop stays reachable
        dialog.raise_()
        dialog.activateWindow()
        return dialog

    def closeEvent(self, event: QCloseEvent) -> None:
        """During a run: press the emergency stop first, then ask (the window stays open meanwhile and closes
        once the stopped run has ended). Otherwise release the robot and close the window's message dialogs."""
        worker = self.campaign_panel.worker
        if worker is not None:
            event.ignore()
            if not self._close_confirmed:
                self.say("window closing during a run: emergency stop first")
                self.emergency_stop()
                self._ask_to_close()
            return
        self.results.stop_watching()
        self.live_view.close_renderer()
        shutdown_worker_process()  # a report being written there still ends; the process then exits
        self.calibration_panel.wait_idle()  # an identification being stored ends before the window goes
        self.robot_panel.wait_idle()
        self.robot_panel.disconnect_robot()
        # its result and error messages go with it: an open one would keep bench gui running, windowless
        for message in self.findChildren(QMessageBox):
            message.close()
        QApplication.instance().removeEventFilter(self._key_filter)
        event.accept()

    def _ask_to_close(self) -> None:
        """The non-modal question of a close during a run (the robot is stopped already)."""
        if self.close_question is not None and self.close_question.isVisible():
            self.close_question.raise_()
            return
        question = QMessageBox(
            QMessageBox.Icon.Question,
            "Close bench?",
            CLOSE_QUESTION,
            QMessageBox.StandardButton.Close | QMessageBox.StandardButton.Cancel,
            self,
        )
        question.setObjectName("closeQuestion")
        question.setWindowModality(Qt.WindowModality.NonModal)
        question.button(QMessageBox.StandardButton.Close).clicked.connect(self.confirm_close)
        self.close_question = question
        question.show()

    def confirm_close(self) -> None:
        """Close the window once the stopped run has ended (at once when it has)."""
        self._close_confirmed = True
        self.campaign_panel.ended_by_operator = True
        if self.campaign_panel.worker is None:
            self.close()
