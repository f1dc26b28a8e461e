"""The window's emergency stop from any state of the window (issue 31, items 1-4), on the simulated pkm5 through
its real link: the STOP is seen on the wire (:class:`gui_support.WireLog`), and every assertion is about order
(STOP before a dialog returns, before a redraw ends, no MOVE after it), never about a clock."""

from __future__ import annotations

import threading

import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, WireLog, serve_events, wait_for
from PySide6.QtCore import Qt, QTimer
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication, QMessageBox

from bench.gui.campaign_panel import EXAMPLES
from bench.gui.robot_panel import LATCHED_TEXT
from bench.store import Store


def _click(widget) -> None:
    QTest.mouseClick(widget, Qt.MouseButton.LeftButton)


def _moving_run(window, *, speed_factor: float = 40.0, samples: int = 2):
    """A long run that is moving once ``samples`` are stored: (its worker, its controller's link observed)."""
    window.robot_panel.speed_factor.setValue(speed_factor)
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / "iso9283_pose_quick.toml")
    panel.form.set_value("cycles", "30")
    panel.form.set_value("settle_s", "0")
    _click(panel.buttons["start"])
    worker = panel.worker
    wait_for(lambda: worker.runner is not None and worker.runner.run_id is not None, RUN_TIMEOUT_S, "the run")
    wire = WireLog(worker.runner.rig.robot.controller)
    wait_for(lambda: panel.progress.value() >= samples, RUN_TIMEOUT_S, f"{samples} stored samples")
    return worker, wire


def _ended_by_the_stop(window, tmp_path):
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the stopped run to end")
    with Store(tmp_path / "bench.db") as store:
        (run,) = store.runs()
    assert (run.status, run.reason) == ("aborted", "emergency stop")


def test_the_stop_reaches_the_wire_while_a_modal_dialog_is_open(window, tmp_path):
    """F12 in a modal dialog (an application-modal one, as Qt's own dialogs can be) stops the robot before the
    dialog returns; the window's own "Open..." dialog is not modal, so the button stays clickable too."""
    _, wire = _moving_run(window)
    mark = wire.mark()
    modal = QMessageBox(QMessageBox.Icon.Information, "modal", "an application-modal dialog", parent=window)
    modal.setWindowModality(Qt.WindowModality.ApplicationModal)
    seen: dict[str, bool] = {}

    def press_f12_then_close() -> None:
        target = QApplication.activeModalWidget()
        if target is None or not target.isVisible():
            QTimer.singleShot(20, press_f12_then_close)  # exec() has not shown it yet
            return
        seen["modal"] = QApplication.activeModalWidget() is modal
        QTest.keyClick(target, Qt.Key.Key_F12)
        poll_until_stopped()

    tries = [0]

    def poll_until_stopped() -> None:
        tries[0] += 1
        if wire.stopped_since(mark) or tries[0] > RUN_TIMEOUT_S * 50:
            seen["stopped before the dialog returned"] = wire.stopped_since(mark)
            modal.done(0)
        else:
            QTimer.singleShot(20, poll_until_stopped)

    QTimer.singleShot(0, press_f12_then_close)
    modal.exec()
    assert seen == {"modal": True, "stopped before the dialog returned": True}
    _ended_by_the_stop(window, tmp_path)
    assert wire.moves_after_stop(mark) == []


def test_the_open_dialog_is_not_modal_and_the_button_stops_the_robot_while_it_is_open(window, tmp_path):
    guard = QTimer()  # were the dialog modal, the click below would not return: close it then, and fail below
    guard.setSingleShot(True)
    guard.timeout.connect(lambda: QApplication.activeModalWidget() and QApplication.activeModalWidget().reject())
    guard.start(5000)
    _click(window.campaign_panel.browse_button)
    guard.stop()
    dialog = window.campaign_panel.file_dialog
    assert dialog is not None and dialog.isVisible() and QApplication.activeModalWidget() is None
    _, wire = _moving_run(window)  # started from the window while the dialog is open
    mark = wire.mark()
    _click(window.estop)
    wait_for(lambda: wire.stopped_since(mark), RUN_TIMEOUT_S, "STOP on the wire")
    assert dialog.isVisible()  # the dialog never had to close for the stop
    _ended_by_the_stop(window, tmp_path)
    assert wire.moves_after_stop(mark) == []
    dialog.reject()


def test_the_stop_reaches_the_wire_while_a_redraw_of_the_live_view_is_in_progress(window, tmp_path, monkeypatch):
    """A redraw held open (a gate in the drawing, as a slow redraw under load) does not hold the stop: STOP is on
    the wire before that redraw ends."""
    from bench.gui import live_view

    _, wire = _moving_run(window)
    drawing, release = threading.Event(), threading.Event()
    order: list[str] = []
    render_picture = live_view._render_picture

    def held_redraw(*args, **kwargs):
        drawing.set()
        release.wait(RUN_TIMEOUT_S)  # bounded: a window that drew on its own thread was held here too
        order.append("STOP out when the redraw ended" if wire.stopped_since(mark) else "redraw ended first")
        return render_picture(*args, **kwargs)

    monkeypatch.setattr(live_view, "_render_picture", held_redraw)
    window.tabs.setCurrentWidget(window.live_view)
    mark = wire.mark()
    QTimer.singleShot(0, window.live_view._timed_redraw)  # the redraw timer's turn...
    QTimer.singleShot(0, lambda: _click(window.estop))  # ...and the operator's click right behind it
    wait_for(lambda: wire.stopped_since(mark) or order, 2 * RUN_TIMEOUT_S, "STOP or the redraw's end")
    release.set()
    wait_for(lambda: order, RUN_TIMEOUT_S, "the held redraw to end")
    assert drawing.is_set() and order[0] == "STOP out when the redraw ended"
    _ended_by_the_stop(window, tmp_path)
    assert wire.moves_after_stop(mark) == []


def test_after_a_jog_emergency_stop_jog_needs_a_reset(window):
    panel = window.robot_panel
    panel.speed_factor.setValue(1)  # real speed: the jog lasts long enough to be stopped in flight
    _click(panel.connect_button)
    wait_for(lambda: panel.mover is not None and not panel.busy(), RUN_TIMEOUT_S, "the simulator connection")
    wire = WireLog(panel.mover.controller)
    panel.velocity.setValue(2.0)  # slow: the move is still under way when the stop comes
    panel.target_boxes[0].setValue(panel.target_boxes[0].value() + 5.0)  # 5 mm along x from home
    assert panel.jog_button.isEnabled(), panel.reach.text()
    _click(panel.jog_button)
    wait_for(lambda: "MOVE" in wire.verbs, RUN_TIMEOUT_S, "the jog's MOVE on the wire")
    mark = wire.mark()
    QTest.keyClick(window, Qt.Key.Key_F12)
    wait_for(lambda: wire.stopped_since(mark) and not panel.busy(), RUN_TIMEOUT_S, "the stopped jog to end")
    assert panel.status.text().startswith(LATCHED_TEXT), panel.status.text()  # not a raw firmware error
    # one click on Jog does not move the robot: the stop is latched until it is reset
    assert not panel.jog_button.isEnabled()
    _click(panel.jog_button)
    panel.jog()
    assert not panel.busy() and wire.moves_after_stop(mark) == [] and wire.verbs[mark:].count("MOVE") == 0
    assert window.reset_estop.isEnabled() and not window.campaign_panel.buttons["start"].isEnabled()
    _click(window.reset_estop)
    wait_for(
        lambda: panel.status.text() == "ready: emergency stop released" and not panel.busy(),
        RUN_TIMEOUT_S,
        "the released latch",
    )
    assert panel.jog_button.isEnabled() and not window.estop_latch.latched
    panel.velocity.setValue(100.0)
    _click(panel.jog_button)
    wait_for(lambda: panel.status.text().startswith("at "), 4 * RUN_TIMEOUT_S, "the jog after the reset")
    assert wire.verbs[mark:].count("MOVE") == 1


def test_closing_the_window_during_a_run_stops_the_robot_first_then_asks(window, tmp_path):
    _, wire = _moving_run(window)
    mark = wire.mark()
    window.close()
    # the press went out within close(): the window asks, and stays responsive meanwhile
    assert window.estop_latch.latched and window.isVisible() and window.close_question.isVisible()
    wait_for(lambda: wire.stopped_since(mark), RUN_TIMEOUT_S, "STOP on the wire")
    assert window.close_question.isVisible()  # STOP went out before the question was answered
    _ended_by_the_stop(window, tmp_path)
    assert wire.moves_after_stop(mark) == []
    assert window.campaign_panel.eta.text().startswith("idle - last: run 1 aborted")  # not "running"
    _click(window.close_question.button(QMessageBox.StandardButton.Close))
    wait_for(lambda: not window.isVisible(), RUN_TIMEOUT_S, "the window to close")
    serve_events(50)
