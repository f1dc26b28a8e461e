"""The kinematic-calibration panel: which calibration the window's runs command by, and identifying a new one.

"In force for runs" chooses, for every run and resume started from the window, what ``bench run`` chooses with its
flags (:mod:`bench.calibration.compensate`, through :func:`bench.launch.open_rig`): the newest calibration of this
robot (default; a resume keeps its run's own), none (``--no-kinematic-calibration``), or one stored calibration by
id (``--kinematic-calibration ID``). The list is the store's calibrations of the robot chosen in the robot panel
(``pkm5_kinematics`` for the pkm5, ``delta4_kinematics`` for the delta4:
:data:`bench.calibration.compensate.CALIBRATION_NAMES`; none for a robot without a calibration model), read again
in the background whenever the robot changes or the results browser sees the store change.

"Identify from the selected run" runs ``bench calibrate``'s function
(:func:`bench.calibration.identify.identify_run`) on the run selected in the results browser, in a background task
(never on the GUI thread; its own store connection), then shows the text ``bench calibrate`` prints, and a dialog;
a refusal (no measured poses, an ill-conditioned pose set) shows its one line. The choices of ``bench calibrate``
sit beside the button: the fit (``--fit``: the robot's default, map or free-set), the instrument's uncertainty
(``--uncertainty-mm``: 0 = the instrument's own) and the target gain the campaign plan is made for
(``--target-gain``); the result shows the whole stored summary (parameters, the robot's scatter apart from the
instrument's, the search, and the plan: cycles per pose and robot time).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QLabel,
    QMessageBox,
    QPlainTextEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from bench.calibration.compensate import CALIBRATION_NAMES, NEWEST, OFF
from bench.calibration.identify import DEFAULT_TARGET_GAIN, FITS, identify_run, summary_lines
from bench.gui.messages import show_message
from bench.gui.tasks import Task, run_in_background
from bench.store import Store

__all__ = ["CalibrationPanel", "stored_calibrations"]


def stored_calibrations(store_path: str, robot: str = "pkm5") -> list:
    """The store's kinematic calibration records of ``robot`` (``<robot>_kinematics``), newest first ([] without a
    store file, or for a robot without a calibration model)."""
    name = CALIBRATION_NAMES.get(robot)
    if name is None or not Path(store_path).is_file():
        return []
    with Store(store_path, read_only=True) as store:
        mine = [c for c in store.calibrations() if c.name == name]
    return sorted(mine, key=lambda c: c.id, reverse=True)


def _describe(record) -> str:
    serial = record.params.get("dut_serial")
    whose = f", robot {serial}" if serial else ""
    simulated = ", simulated" if record.params.get("simulated") else ""
    return f"{record.name} v{record.version} (id {record.id}, from run {record.source_run_id}{whose}{simulated})"


def _identify(store_path: str, run_id: int, options: dict):
    with Store(store_path) as store:
        return identify_run(store, run_id, **options)


class CalibrationPanel(QGroupBox):
    """The calibration in force for the window's runs, and identification from a run of ``selected_runs()``.

    Attributes
    ----------
    last_dialog : QMessageBox or None
        The latest result or error dialog (non-modal).
    last_identified : bench.calibration.identify.IdentifiedRun or None
        The latest identification made from the window.
    """

    message = Signal(str)
    identified = Signal(object)  #: an :class:`bench.calibration.identify.IdentifiedRun`

    def __init__(
        self,
        store_path: str,
        selected_runs: Callable[[], list[int]],
        parent: QWidget | None = None,
        *,
        robot: Callable[[], str] = lambda: "pkm5",
    ) -> None:
        super().__init__("Kinematic calibration", parent)
        self.store_path = store_path
        self.selected_runs = selected_runs
        self.robot = robot  #: the robot whose calibrations are listed (the robot panel's)
        self._stale = False
        self.last_dialog: QMessageBox | None = None
        self.last_identified = None
        self._task: Task | None = None
        self._scan: Task | None = None
        self.choice_box = QComboBox()
        self.choice_box.setObjectName("kinematicCalibration")
        self.choice_box.setToolTip(
            "The kinematic calibration the runs started from this window command by "
            "(bench run --kinematic-calibration ID / --no-kinematic-calibration)"
        )
        self._fill(self.robot(), [])
        self.identify_button = QPushButton("Identify from the selected run")
        self.identify_button.setObjectName("identifyButton")
        self.identify_button.setToolTip(
            "bench calibrate RUN_ID on the run selected in the Results tab: identify "
            "the robot's geometry and store it as a new <robot>_kinematics version"
        )
        self.identify_button.clicked.connect(lambda _=False: self.identify())
        self.fit_box = QComboBox()
        self.fit_box.setObjectName("calibrationFit")
        self.fit_box.addItem("default (map)", None)
        for fit in FITS:
            self.fit_box.addItem(fit, fit)
        self.fit_box.setToolTip(
            "bench calibrate --fit: map fits every parameter with the tolerances as the prior; "
            "free-set only what the poses identify"
        )
        self.uncertainty_box = QDoubleSpinBox()
        self.uncertainty_box.setObjectName("calibrationUncertainty")
        self.uncertainty_box.setRange(0.0, 10.0)
        self.uncertainty_box.setDecimals(3)
        self.uncertainty_box.setSingleStep(0.01)
        self.uncertainty_box.setSuffix(" mm")
        self.uncertainty_box.setSpecialValueText("the instrument's")
        self.uncertainty_box.setToolTip(
            "bench calibrate --uncertainty-mm: the instrument's standard uncertainty "
            "per reading, the floor of the measured scatter (0: the instrument's own)"
        )
        self.gain_box = QDoubleSpinBox()
        self.gain_box.setObjectName("calibrationTargetGain")
        self.gain_box.setRange(1.5, 1000.0)
        self.gain_box.setValue(DEFAULT_TARGET_GAIN)
        self.gain_box.setSuffix(" x")
        self.gain_box.setToolTip(
            "bench calibrate --target-gain: the held-out AP gain the campaign plan (cycles per "
            "pose, robot time) is made for"
        )
        self.status = QLabel("")
        self.status.setObjectName("calibrationStatus")
        self.status.setWordWrap(True)
        self.result_text = QPlainTextEdit()
        self.result_text.setObjectName("calibrationResult")
        self.result_text.setReadOnly(True)
        self.result_text.setMaximumHeight(220)
        self.result_text.setPlaceholderText("identified parameters, uncertainties and observability")
        form = QFormLayout()
        form.addRow("In force for runs", self.choice_box)
        form.addRow("Fit", self.fit_box)
        form.addRow("Instrument uncertainty", self.uncertainty_box)
        form.addRow("Plan for gain", self.gain_box)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(self.identify_button)
        layout.addWidget(self.status)
        layout.addWidget(self.result_text)
        self.refresh()

    # ---- the calibration in force ----------------------------------------------------------------------------

    def choice(self) -> int | str:
        """:data:`NEWEST`, :data:`OFF` or a calibration id: what the window's runs command by."""
        return self.choice_box.currentData()

    def choose(self, choice: int | str) -> None:
        """Select ``choice`` (NEWEST, OFF or a listed calibration id); an id not listed raises ``ValueError``."""
        index = self.choice_box.findData(choice)
        if index < 0:
            raise ValueError(f"calibration {choice!r} is not listed")
        self.choice_box.setCurrentIndex(index)

    def _fill(self, robot: str, records: list) -> None:
        current = self.choice_box.currentData() if self.choice_box.count() else NEWEST
        self.choice_box.blockSignals(True)
        self.choice_box.clear()
        self.choice_box.addItem("newest for this robot", NEWEST)
        self.choice_box.addItem("none (documented geometry)", OFF)
        for record in records:
            self.choice_box.addItem(_describe(record), record.id)
        index = self.choice_box.findData(current)
        self.choice_box.setCurrentIndex(index if index >= 0 else 0)
        self.choice_box.blockSignals(False)
        if index < 0:
            self.message.emit(
                f"kinematic calibration id {current} is not a stored calibration of the {robot}: newest chosen"
            )

    def refresh(self) -> Task:
        """Read the robot's stored calibrations again in the background; the list follows (a call during a scan
        scans again when that one ends: the robot or the store may have changed meanwhile)."""
        if self._scan is not None:
            self._stale = True
            return self._scan
        path, robot = self.store_path, self.robot()
        self._scan = run_in_background(
            "reading the calibrations",
            lambda: stored_calibrations(path, robot),
            self,
            on_done=lambda records: self._fill(robot, records),
            on_failed=self.message.emit,
            on_ended=self._scanned,
        )
        return self._scan

    def _scanned(self) -> None:
        self._scan = None
        if self._stale:
            self._stale = False
            self.refresh()

    # ---- identification --------------------------------------------------------------------------------------

    def identify_options(self) -> dict:
        """The keyword arguments of :func:`identify_run` the box's choices give (``bench calibrate``'s flags)."""
        uncertainty = self.uncertainty_box.value()
        return {
            "fit": self.fit_box.currentData(),
            "uncertainty_mm": uncertainty if uncertainty > 0 else None,
            "target_gain": self.gain_box.value(),
        }

    def identify(self) -> Task | None:
        """``bench calibrate`` on the selected run, in the background; the result is shown when it is stored."""
        ids = self.selected_runs()
        if len(ids) != 1:
            self.message.emit("Identify: select one run (a kinematic calibration run) in the Results tab")
            return None
        if self._task is not None:
            self.message.emit("Identify: an identification is running")
            return None
        run_id = ids[0]
        self.status.setText(f"identifying the geometry from run {run_id}...")
        self.identify_button.setEnabled(False)
        path, options = self.store_path, self.identify_options()
        self._task = run_in_background(
            f"identification from run {run_id}",
            lambda: _identify(path, run_id, options),
            self,
            on_done=self._identified,
            on_failed=lambda text: self._failed(run_id, text),
            on_ended=self._ended,
        )
        return self._task

    def _identified(self, identified) -> None:
        self.last_identified = identified
        lines = summary_lines(identified)
        self.result_text.setPlainText("\n".join(lines))
        self.status.setText(lines[0])
        self.message.emit(lines[0])
        self.last_dialog = show_message(
            self,
            QMessageBox.Icon.Information,
            "Calibration stored",
            "\n".join([lines[0], *lines[2 + len(identified.result.names) :]]),
            name="calibrationDialog",
        )
        self.refresh()
        self.identified.emit(identified)

    def _failed(self, run_id: int, text: str) -> None:
        self.status.setText(f"not identified: {text}")
        self.message.emit(text)
        self.last_dialog = show_message(
            self, QMessageBox.Icon.Warning, f"Run {run_id} not identified", text, name="calibrationDialog"
        )

    def _ended(self) -> None:
        self._task = None
        self.identify_button.setEnabled(True)

    def busy(self) -> bool:
        return self._task is not None

    def wait_idle(self, timeout_s: float = 60.0) -> bool:
        """Wait (without the event loop: the window is closing) until a running identification has ended; True
        when none is left running."""
        deadline = time.monotonic() + timeout_s
        while self._task is not None and not self._task.finished and time.monotonic() < deadline:
            time.sleep(0.05)
        return self._task is None or self._task.finished
