"""The campaign panel: pick a protocol file, edit its parameters, see the pre-flight and the estimated duration,
queue runs, start / pause / resume / stop / abort them, and follow the progress with an ETA.

The pre-flight is :func:`bench.protocols.summarize` (every target checked in motion/ before anything moves) and
the runs go to a :class:`bench.gui.worker.CampaignWorker`, which calls the same rig builder and runner as
``bench run``. The panel only presents: the run buttons follow the runner's state machine
(:data:`bench.protocols.runner.TRANSITIONS`; a button is enabled only for a legal transition), the protocol form
is locked while a campaign runs, and the status line says how the last run ended, with its counts.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QVBoxLayout,
    QWidget,
)

from bench.errors import BenchError
from bench.gui.estop import EmergencyStop
from bench.gui.parameter_form import ParameterForm
from bench.gui.worker import CampaignWorker, RigSpec
from bench.protocols import Protocol, RunResult, RunState, load_protocol, summarize
from bench.protocols.plan import PlanSummary
from bench.protocols.runner import TRANSITIONS

__all__ = ["ACTION_TARGETS", "CampaignPanel", "enabled_actions", "example_protocols", "format_duration"]

#: The runner state each run button asks for.
ACTION_TARGETS = {
    "pause": RunState.PAUSED,
    "resume": RunState.RUNNING,
    "stop": RunState.STOPPING,
    "abort": RunState.ABORTING,
}
#: The worker's "pause requested": still running, a second pause means nothing.
PAUSE_REQUESTED = "pause requested"


def enabled_actions(state: str | None) -> set[str]:
    """The run buttons that are legal in the worker's ``state`` (a :class:`RunState` value, "pause requested",
    "starting", or None when no campaign runs): those whose target state ``TRANSITIONS`` allows."""
    if state is None:
        return {"start"}
    try:
        current = RunState.RUNNING if state == PAUSE_REQUESTED else RunState(state)
    except ValueError:  # starting: the rig is being built, only the emergency stop acts
        return set()
    if current is RunState.IDLE:  # the runner exists but has not started the run yet
        return set()
    legal = {action for action, target in ACTION_TARGETS.items() if target in TRANSITIONS[current]}
    return legal - {"pause"} if state == PAUSE_REQUESTED else legal


#: Where the protocol library of the repository lives (offered in the file list when present).
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def example_protocols() -> list[Path]:
    """The example protocol files shipped with bench, by name."""
    return sorted(EXAMPLES.glob("*.toml")) if EXAMPLES.is_dir() else []


def format_duration(seconds: float) -> str:
    """``h:mm:ss`` (or ``m:ss`` under an hour)."""
    seconds = max(0, round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


class CampaignPanel(QGroupBox):
    """Protocol, parameters, pre-flight, queue and run controls.

    Parameters
    ----------
    store_path : str
        The run store the worker writes to.
    rig_spec : callable
        Returns the :class:`RigSpec` chosen in the robot panel (asked when a run starts).
    estop : EmergencyStop, optional
        The window's emergency stop: each worker's stop is registered with it, and nothing starts while it is
        latched.
    """

    worker_started = Signal(object)  #: the new :class:`CampaignWorker`, for the window to connect
    message = Signal(str)

    def __init__(
        self,
        store_path: str,
        rig_spec: Callable[..., RigSpec],
        parent: QWidget | None = None,
        *,
        estop: EmergencyStop | None = None,
    ) -> None:
        super().__init__("Campaign", parent)
        self.store_path = store_path
        self.rig_spec = rig_spec
        self.estop = estop or EmergencyStop()
        self.worker: CampaignWorker | None = None
        self.summary: PlanSummary | None = None
        self.queue: list[Protocol] = []
        self._started_s = 0.0
        self._done_at_start = 0
        self.state: str | None = None  #: the worker's state (None: no campaign)
        self.last_outcome = ""  #: how the last run ended, e.g. "run 3 aborted (175 / 450 samples): emergency stop"
        self.ended_by_operator = False  #: Stop, Abort or the window closing ended the current campaign
        self.file_dialog: QFileDialog | None = None  #: the last "Open..." dialog
        layout = QVBoxLayout(self)
        layout.addLayout(self._file_row())
        self.form = ParameterForm()
        self.form.changed.connect(self._form_changed)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.form)
        scroll.setMinimumHeight(180)
        layout.addWidget(scroll, 1)
        self.preflight = QLabel("choose a protocol file")
        self.preflight.setObjectName("preflight")
        self.preflight.setWordWrap(True)
        layout.addWidget(self.preflight)
        options = QHBoxLayout()
        self.campaign = QLineEdit()
        self.campaign.setPlaceholderText("campaign name (optional)")
        self.simulated_calliper = QCheckBox("simulated calliper answers readings")
        options.addWidget(self.campaign)
        options.addWidget(self.simulated_calliper)
        layout.addLayout(options)
        layout.addWidget(self._queue_box())
        layout.addLayout(self._control_row())
        self.progress = QProgressBar()
        self.progress.setObjectName("campaignProgress")
        self.progress.setFormat("%v / %m samples")
        self.eta = QLabel("idle")
        self.eta.setObjectName("campaignEta")
        self.eta.setWordWrap(True)  # a long outcome wraps: it would widen the panel and squeeze the live view
        layout.addWidget(self.progress)
        layout.addWidget(self.eta)
        self._set_running(False)
        if self.files.count():
            self.choose_file(self.files.currentData())

    # ---- protocol and parameters ---------------------------------------------------------------------------

    def _file_row(self) -> QHBoxLayout:
        row = QHBoxLayout()
        self.files = QComboBox()
        self.files.setObjectName("protocolFiles")
        for path in example_protocols():
            self.files.addItem(path.name, str(path))
        quick = self.files.findText("iso9283_pose_quick.toml")
        if quick >= 0:
            self.files.setCurrentIndex(quick)
        self.files.activated.connect(lambda _: self.choose_file(self.files.currentData()))
        self.browse_button = QPushButton("Open…")
        self.browse_button.clicked.connect(self._browse)
        row.addWidget(QLabel("Protocol"))
        row.addWidget(self.files, 1)
        row.addWidget(self.browse_button)
        return row

    def _browse(self) -> None:
        """A non-modal file dialog: a modal one would block the window, its emergency stop button included."""
        dialog = QFileDialog(self, "Protocol file", str(EXAMPLES), "Protocols (*.toml)")
        dialog.setObjectName("protocolFileDialog")
        dialog.setFileMode(QFileDialog.FileMode.ExistingFile)
        dialog.setOption(QFileDialog.Option.DontUseNativeDialog)  # a desktop's native one may be modal regardless
        dialog.setWindowModality(Qt.WindowModality.NonModal)
        dialog.fileSelected.connect(self._file_chosen)
        dialog.finished.connect(dialog.deleteLater)
        self.file_dialog = dialog
        dialog.show()

    def _file_chosen(self, path: str) -> None:
        if path:
            self.files.addItem(Path(path).name, path)
            self.files.setCurrentIndex(self.files.count() - 1)
            self.choose_file(path)

    def choose_file(self, path: str | Path) -> None:
        """Load a protocol file into the form (the robot comes from the robot panel)."""
        robot = self.rig_spec().robot
        try:
            protocol = load_protocol(path, robot=robot)
        except BenchError as exc:
            self.preflight.setText(f"<span style='color:#b00020'>{exc}</span>")
            self.message.emit(str(exc))
            return
        self.form.load(protocol, fixed={"robot": robot})

    def _form_changed(self, protocol: Protocol | None, errors: list[str]) -> None:
        self.summary = None
        if protocol is None:
            self.preflight.setText("<span style='color:#b00020'>" + "<br>".join(errors) + "</span>")
        else:
            self.summary = summarize(protocol)
            self.preflight.setText(self._describe(self.summary))
        self._set_running(self.worker is not None)

    def _describe(self, summary: PlanSummary) -> str:
        counts = ", ".join(f"{n} {kind}" for kind, n in summary.counts.items())
        speed = self.rig_spec().speed_factor if self.rig_spec().port is None else 1.0
        timing = f"estimated {format_duration(summary.estimated_s)} at real speed"
        if speed > 1:
            timing += f", about {format_duration(summary.estimated_s / speed)} simulated (prompts excepted)"
        if summary.ok:
            return (
                f"<span style='color:#1b5e20'>pre-flight OK</span>: {len(summary.labels)} targets; {counts}; {timing}"
            )
        return "<span style='color:#b00020'>pre-flight REFUSED</span>: " + "<br>".join(summary.problems())

    # ---- queue and controls --------------------------------------------------------------------------------

    def _queue_box(self) -> QGroupBox:
        box = QGroupBox("Queue")
        row = QHBoxLayout(box)
        self.queue_list = QListWidget()
        self.queue_list.setMaximumHeight(70)
        buttons = QVBoxLayout()
        self.add_button = QPushButton("Add to queue")
        self.add_button.clicked.connect(self.add_to_queue)
        self.remove_button = QPushButton("Remove")
        self.remove_button.clicked.connect(self._remove_from_queue)
        buttons.addWidget(self.add_button)
        buttons.addWidget(self.remove_button)
        row.addWidget(self.queue_list, 1)
        row.addLayout(buttons)
        return box

    def add_to_queue(self) -> bool:
        """Queue the protocol as the form shows it, if its pre-flight passed."""
        protocol = self.form.protocol
        if protocol is None or self.summary is None or not self.summary.ok:
            self.message.emit("not queued: fix the parameters or the pre-flight first")
            return False
        self.queue.append(protocol)
        self.queue_list.addItem(f"{protocol.name} ({protocol.robot}, {self.form.source})")
        return True

    def _remove_from_queue(self) -> None:
        row = self.queue_list.currentRow()
        if row >= 0:
            self.queue_list.takeItem(row)
            del self.queue[row]

    def _control_row(self) -> QHBoxLayout:
        row = QHBoxLayout()
        self.buttons: dict[str, QPushButton] = {}
        for action, text in (
            ("start", "Start"),
            ("pause", "Pause"),
            ("resume", "Resume"),
            ("stop", "Stop"),
            ("abort", "Abort"),
        ):
            button = QPushButton(text)
            button.setObjectName(f"{action}Button")
            button.clicked.connect(lambda _=False, a=action: self.start() if a == "start" else self.request(a))
            row.addWidget(button)
            self.buttons[action] = button
        return row

    def _set_running(self, running: bool) -> None:
        self._set_state(self.state if running else None)

    def _set_state(self, state: str | None) -> None:
        """Enable what ``state`` allows: the legal run buttons; the form, file and queue only without a campaign."""
        self.state = state
        ready = self.summary is not None and self.summary.ok
        legal = enabled_actions(state)
        self.buttons["start"].setEnabled("start" in legal and (ready or bool(self.queue)) and not self.estop.latched)
        for action in ACTION_TARGETS:
            self.buttons[action].setEnabled(action in legal)
        idle = state is None
        for widget in (
            self.form,
            self.files,
            self.browse_button,
            self.campaign,
            self.simulated_calliper,
            self.remove_button,
        ):
            widget.setEnabled(idle)
        self.add_button.setEnabled(idle and ready)

    def start(self, jobs: list[Protocol | int] | None = None) -> CampaignWorker | None:
        """Run the queue (or the protocol in the form when the queue is empty), or resume stored runs (ids)."""
        if self.worker is not None:
            self.message.emit("a campaign is running: wait for it to end")
            return None
        if self.estop.latched:
            self.message.emit("not started: the emergency stop is latched (check the robot, then Reset e-stop)")
            return None
        if jobs is None:
            if not self.queue and not self.add_to_queue():
                return None
            jobs, self.queue = list(self.queue), []
            self.queue_list.clear()
        spec = self.rig_spec(simulated_calliper=self.simulated_calliper.isChecked())
        worker = CampaignWorker(self.store_path, jobs, spec, campaign=self.campaign.text().strip() or None, parent=self)
        worker.run_started.connect(self._run_started)
        worker.sample_stored.connect(self._sample_stored)
        worker.state_changed.connect(self._state_changed)
        worker.run_finished.connect(self._run_finished)
        worker.failed.connect(self._failed)
        worker.message.connect(self.message.emit)
        worker.finished.connect(self._worker_finished)
        self.worker = worker
        self.estop.register(worker.emergency_stop)
        self.ended_by_operator = False
        self._set_state("starting")
        self.eta.setText("starting the rig")
        self.worker_started.emit(worker)
        worker.start()
        return worker

    def request(self, action: str) -> None:
        if self.worker is not None:
            if action in ("stop", "abort", "halt"):
                self.ended_by_operator = True
            self.worker.request(action)

    def _state_changed(self, state: str) -> None:
        runner = self.worker.runner if self.worker is not None else None
        if runner is not None and state != PAUSE_REQUESTED:
            # the runner's own state: a report queued before a later request is stale; idle = still starting
            state = "starting" if runner.state is RunState.IDLE else runner.state.value
        self._set_state(state)
        self.eta.setText(f"{state} - {self._eta_text()}")

    def _run_finished(self, result: RunResult) -> None:
        reason = f": {result.reason}" if result.reason else ""
        self.last_outcome = (
            f"run {result.run_id} {result.exit_status} ({result.samples} / {self.progress.maximum()} samples){reason}"
        )
        self.eta.setText(self.last_outcome)

    def _failed(self, text: str) -> None:
        self.last_outcome = f"not started: {text}"
        self.message.emit(text)

    def _run_started(self, run_id: int, total: int, done: int) -> None:
        self._started_s = time.monotonic()
        self._done_at_start = done
        self.progress.setRange(0, max(total, 1))
        self.progress.setValue(done)
        self.eta.setText(f"run {run_id} started")

    def _sample_stored(self, run_id: int, sample: dict) -> None:
        self.progress.setValue(self.progress.value() + 1)
        self.eta.setText(f"run {run_id}: {self._eta_text()}")

    def _eta_text(self) -> str:
        done, total = self.progress.value(), self.progress.maximum()
        elapsed = time.monotonic() - self._started_s
        taken = done - self._done_at_start  # this session's rate sets the ETA (a resumed run started part-way)
        if taken <= 0:
            return f"{done} / {total} samples"
        remaining = elapsed / taken * (total - done)
        return f"{done} / {total} samples, elapsed {format_duration(elapsed)}, ETA {format_duration(remaining)}"

    def refresh_buttons(self) -> None:
        """Enable the buttons again for the current state (the emergency stop latched or was reset)."""
        self._set_state(self.state)

    def _worker_finished(self) -> None:
        if self.worker is not None:
            self.estop.unregister(self.worker.emergency_stop)
        self.worker = None
        self._set_state(None)
        self.eta.setText(f"idle - last: {self.last_outcome}" if self.last_outcome else "idle")

    def shut_down(self, timeout_s: float = 60.0) -> bool:
        """Stop the worker safely (resumable) and wait for it; True when it ended within ``timeout_s``."""
        worker = self.worker
        if worker is None:
            return True
        self.ended_by_operator = True
        worker.shut_down()
        return worker.wait(int(timeout_s * 1000))
