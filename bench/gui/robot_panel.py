"""The robot panel: choose the robot and its connection, connect, and jog to a pose checked before it moves.

Every jog target goes through the protocols' pre-flight model (:func:`bench.protocols.kinematics.robot_model`:
inverse kinematics from motion/, joint limits, singularity proximity) as it is typed; the Jog button is enabled
only for a target proved reachable. The simulator connection is the same simulated rig a campaign uses
(:func:`bench.simulators.rig.simulated_rig`); a serial connection opens the robot's real driver on the port.
Moves run in a :class:`QThread`, so the window stays responsive.

The emergency stop (:class:`bench.gui.estop.EmergencyStop`) reaches the jogging robot through its stop thread (the
mover's latching ``emergency_stop``); after it Jog stays disabled until the operator resets the stop, which releases
the robot's latch (``release_stop``: the pkm5's drives are enabled again) off the window's thread.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QThread, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from bench.errors import BenchError
from bench.gui.estop import EmergencyStop
from bench.gui.worker import RigSpec
from bench.protocols.kinematics import DEFAULT_SINGULARITY_THRESHOLD, robot_model
from bench.rigs.mice_liveness import XZ_MOUNTS, XZ_PLATFORM
from bench.robot_kinds import robot_names

__all__ = ["RobotPanel", "check_target", "open_mover"]

_log = logging.getLogger(__name__)
_BOUND_MM_DEG = 1000.0
#: The robot panel's status while the emergency stop is latched.
LATCHED_TEXT = "EMERGENCY STOP latched: check the robot, then Reset e-stop"


def check_target(robot: str, target: tuple[float, ...]) -> tuple[bool, str]:
    """(reachable, explanation) of one jog target in mm and degrees, from the pre-flight model."""
    model = robot_model(robot)
    check = model.check(model.as_targets([target]), DEFAULT_SINGULARITY_THRESHOLD)
    if bool(check.reachable[0]):
        return True, f"reachable (singularity proximity {check.proximity[0]:.3f})"
    return False, f"NOT reachable: {check.reason[0]}"


def open_mover(spec: RigSpec) -> tuple[Any, Callable[[], None]]:
    """A connected robot (``move_to``, ``stop``, ``shutdown``, ``settings``) and the function that releases it,
    opened by the same code as a run's rig (:func:`bench.launch.open_mover`)."""
    from bench.launch import open_mover as launch_open_mover

    return launch_open_mover(spec.request(), spec.robot)


class _Call(QThread):
    """Runs one function off the GUI thread; ``done(result)`` or ``error(message)``."""

    done = Signal(object)
    error = Signal(str)

    def __init__(self, function: Callable[[], Any], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.function = function

    def run(self) -> None:
        try:
            self.done.emit(self.function())
        except BenchError as exc:
            self.error.emit(str(exc))
        except Exception as exc:  # noqa: BLE001 - shown to the operator, never a silent thread death
            _log.exception("robot panel call failed")
            self.error.emit(f"{type(exc).__name__}: {exc}")


class RobotPanel(QGroupBox):
    """Robot, connection, status and jog; ``connection_changed(connected)`` tells the window."""

    connection_changed = Signal(bool)
    message = Signal(str)

    def __init__(self, parent: QWidget | None = None, *, estop: EmergencyStop | None = None) -> None:
        super().__init__("Robot", parent)
        self.estop = estop or EmergencyStop()
        self.estop.register(self._stop_jog_robot)
        self.mover: Any = None
        self._release: Callable[[], None] | None = None
        self._call: _Call | None = None
        form = QFormLayout()
        self.robot = QComboBox()
        self.robot.addItems(list(robot_names()))
        self.connection = QComboBox()
        self.connection.addItems(["simulator", "serial port"])
        self.port = QLineEdit()
        self.port.setPlaceholderText("/dev/ttyUSB0")
        self.seed = QSpinBox()
        self.seed.setRange(0, 2**31 - 1)
        self.speed_factor = QDoubleSpinBox()
        self.speed_factor.setRange(1.0, 1e6)
        self.speed_factor.setDecimals(0)
        self.speed_factor.setValue(10000.0)
        self.mouse_xy, self.mouse_xz = QLineEdit(), QLineEdit()
        self.mouse_xy.setPlaceholderText("/dev/input/by-id/...-event-mouse (hardware campaigns)")
        self.mouse_xz.setPlaceholderText("/dev/input/by-id/...-event-mouse (hardware campaigns)")
        self.mouse_xz_mount = QComboBox()  # [mice] xz_mount: the x-z mouse on the platform, or on vertical guides
        self.mouse_xz_mount.addItems(list(XZ_MOUNTS))
        for label, widget in (
            ("Robot", self.robot),
            ("Connection", self.connection),
            ("Port", self.port),
            ("Simulator seed", self.seed),
            ("Speed factor", self.speed_factor),
            ("Mouse x-y", self.mouse_xy),
            ("Mouse x-z", self.mouse_xz),
            ("Mouse x-z mount", self.mouse_xz_mount),
        ):
            form.addRow(label, widget)
        self.connect_button = QPushButton("Connect")
        self.connect_button.setObjectName("connectButton")
        self.connect_button.clicked.connect(self.toggle_connection)
        self.status = QLabel("disconnected")
        self.status.setObjectName("robotStatus")
        self.status.setWordWrap(True)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        row = QHBoxLayout()
        row.addWidget(self.connect_button)
        row.addWidget(self.status, 1)
        layout.addLayout(row)
        layout.addWidget(self._jog_box())
        layout.addStretch(1)
        self.robot.currentTextChanged.connect(self._robot_changed)
        self.connection.currentTextChanged.connect(self._connection_kind_changed)
        self._robot_changed(self.robot.currentText())
        self._connection_kind_changed(self.connection.currentText())

    # ---- settings ------------------------------------------------------------------------------------------

    def rig_spec(self, *, simulated_calliper: bool = False) -> RigSpec:
        """The robot and connection chosen, as a campaign's :class:`RigSpec`."""
        serial_port = self.connection.currentText() == "serial port"
        port = self.port.text().strip() if serial_port else None
        mice = (
            (self.mouse_xy.text().strip() or None, self.mouse_xz.text().strip() or None)
            if serial_port
            else (None, None)
        )
        mount = self.mouse_xz_mount.currentText()
        return RigSpec(
            robot=self.robot.currentText(),
            port=port or None,
            seed=self.seed.value(),
            speed_factor=self.speed_factor.value(),
            mouse_xy=mice[0],
            mouse_xz=mice[1],
            # the station default is the platform; only a guided mount is asked for, and only with mice
            mouse_xz_mount=mount if any(mice) and mount != XZ_PLATFORM else None,
            simulated_calliper=simulated_calliper,
        )

    def _connection_kind_changed(self, kind: str) -> None:
        serial_port = kind == "serial port"
        for widget in (self.port, self.mouse_xy, self.mouse_xz, self.mouse_xz_mount):
            widget.setEnabled(serial_port)
        for widget in (self.seed, self.speed_factor):
            widget.setEnabled(not serial_port)

    # ---- jog -----------------------------------------------------------------------------------------------

    def _jog_box(self) -> QGroupBox:
        box = QGroupBox("Jog (pre-flight checked)")
        self._jog_form = QFormLayout(box)
        self.target_boxes: list[QDoubleSpinBox] = []
        self.velocity = QDoubleSpinBox()
        self.velocity.setRange(0.1, 100.0)
        self.velocity.setValue(20.0)
        self.velocity.setSuffix(" %")
        self.reach = QLabel("")
        self.reach.setObjectName("reachability")
        self.reach.setWordWrap(True)
        self.jog_button = QPushButton("Jog")
        self.jog_button.setObjectName("jogButton")
        self.jog_button.clicked.connect(self.jog)
        self.home_button = QPushButton("Home target")
        self.home_button.clicked.connect(self.set_home_target)
        self._fixed_rows = (("Velocity", self.velocity), ("Pre-flight", self.reach))
        return box

    def _robot_changed(self, robot: str) -> None:
        while self._jog_form.rowCount():
            self._jog_form.takeRow(0)
        self.target_boxes = []
        for field in robot_model(robot).target_fields:
            spin = QDoubleSpinBox()
            spin.setRange(-_BOUND_MM_DEG, _BOUND_MM_DEG)
            spin.setDecimals(3)
            spin.setSuffix(" " + field.rsplit("_", 1)[1])
            spin.valueChanged.connect(self.update_reachability)
            self.target_boxes.append(spin)
            self._jog_form.addRow(field, spin)
        for label, widget in self._fixed_rows:
            self._jog_form.addRow(label, widget)
        buttons = QWidget()
        row = QHBoxLayout(buttons)
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(self.home_button)
        row.addWidget(self.jog_button)
        self._jog_form.addRow(buttons)
        self.set_home_target()

    def target(self) -> tuple[float, ...]:
        return tuple(spin.value() for spin in self.target_boxes)

    def set_target(self, target: tuple[float, ...]) -> None:
        for spin, value in zip(self.target_boxes, target, strict=True):
            spin.blockSignals(True)
            spin.setValue(value)
            spin.blockSignals(False)
        self.update_reachability()

    def set_home_target(self) -> None:
        self.set_target(robot_model(self.robot.currentText()).home)

    def update_reachability(self) -> bool:
        """Pre-flight the target shown; enable Jog only when it is reachable and a robot is connected."""
        reachable, text = check_target(self.robot.currentText(), self.target())
        self.reach.setText(text)
        self.reach.setStyleSheet("color: #1b5e20" if reachable else "color: #b00020")
        self.jog_button.setEnabled(
            reachable and self.mover is not None and self._call is None and not self.estop.latched
        )
        return reachable

    def jog(self) -> None:
        """Move to the target, after checking it again (never move to an unchecked target)."""
        if self.mover is None or not self.update_reachability() or self.estop.latched:
            return
        target, velocity = self.target(), self.velocity.value()
        self.status.setText(f"moving to {', '.join(f'{v:g}' for v in target)}")
        self._start(
            lambda: self.mover.move_to(target, velocity_pct=velocity),
            lambda _: self.status.setText(f"at {', '.join(f'{v:g}' for v in target)}"),
        )

    # ---- connection ----------------------------------------------------------------------------------------

    def toggle_connection(self) -> None:
        if self.mover is None:
            self.connect_robot()
        else:
            self.disconnect_robot()

    def connect_robot(self) -> None:
        """Open the chosen connection in the background; the status says when it is ready."""
        spec = self.rig_spec()
        self.status.setText(f"connecting to the {spec.robot} {spec.port or 'simulator'}...")
        self.connect_button.setEnabled(False)
        self._start(lambda: open_mover(spec), self._connected)

    def _connected(self, result: tuple[Any, Callable[[], None]]) -> None:
        self.mover, self._release = result
        settings = self.mover.settings()
        self.status.setText("connected: " + ", ".join(f"{k}={v}" for k, v in list(settings.items())[:3]))
        self.connect_button.setText("Disconnect")
        self.connect_button.setEnabled(True)
        self.robot.setEnabled(False)
        self.connection.setEnabled(False)
        self.update_reachability()
        self.connection_changed.emit(True)

    def disconnect_robot(self) -> None:
        """Shut the robot down to a safe state and release the port or the simulator."""
        if self._call is not None:
            self._call.wait(30_000)
        release, self.mover, self._release = self._release, None, None
        if release is not None:
            try:
                release()
            except BenchError as exc:
                self.message.emit(f"disconnect: {exc}")
        self.status.setText("disconnected")
        self.connect_button.setText("Connect")
        self.connect_button.setEnabled(True)
        self.robot.setEnabled(True)
        self.connection.setEnabled(True)
        self.update_reachability()
        self.connection_changed.emit(False)

    def _stop_jog_robot(self) -> None:
        """The stop thread's part (never the window's thread): the jogging robot's latching stop."""
        mover = self.mover
        if mover is not None:
            getattr(mover, "emergency_stop", mover.stop)()

    def emergency_stop(self) -> None:
        """Press the emergency stop (the stop thread stops the jogging robot) and show the latch."""
        self.estop.press()
        self.show_latched()

    def show_latched(self) -> None:
        """The stop is latched: say so, and no Jog until it is reset."""
        if self.mover is not None:
            self.status.setText(LATCHED_TEXT)
        self.update_reachability()

    def release_stop(self) -> None:
        """After the operator reset the emergency stop: release the jogging robot's latch (off the window's
        thread: the pkm5's ENABLE waits for its reply)."""
        mover = self.mover
        if mover is None or not hasattr(mover, "release_stop"):
            self.update_reachability()
            return
        self.status.setText("releasing the emergency stop")
        self._start(mover.release_stop, lambda _: self.status.setText("ready: emergency stop released"))

    def _start(self, function: Callable[[], Any], on_done: Callable[[Any], None]) -> None:
        call = _Call(function, self)
        self._call = call
        call.done.connect(on_done)
        call.error.connect(self._failed)
        call.finished.connect(self._call_finished)
        self.jog_button.setEnabled(False)
        call.start()

    def _failed(self, text: str) -> None:
        # a move the emergency stop cut short ends with the controller's error: the latch is the news
        self.status.setText(f"{LATCHED_TEXT} (the move ended: {text})" if self.estop.latched else f"error: {text}")
        self.connect_button.setEnabled(True)
        self.message.emit(text)

    def _call_finished(self) -> None:
        self._call = None
        self.update_reachability()

    def busy(self) -> bool:
        return self._call is not None

    def wait_idle(self, timeout_ms: int = 30_000) -> None:
        if self._call is not None:
            self._call.wait(timeout_ms)
