"""The window's run queue, comparison of two runs, the emergency stop during a campaign, and withdrawn calliper
prompts: cancelled in the dialog, or the window closed while a reading is pending (simulated pkm5)."""

from __future__ import annotations

import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, WireLog, select_runs, wait_for
from PySide6.QtCore import Qt
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QMessageBox

from bench.gui.campaign_panel import EXAMPLES
from bench.protocols import Settle
from bench.store import Store


def _runs(tmp_path):
    with Store(tmp_path / "bench.db") as store:
        return store.runs(), {r.id: store.samples(r.id) for r in store.runs()}


@pytest.mark.slow
def test_queued_runs_run_in_order_and_two_runs_compare(window, tmp_path):
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / "iso9283_pose_quick.toml")
    panel.campaign.setText("queue test")
    for cycles in ("2", "3"):
        panel.form.set_value("cycles", cycles)
        assert panel.add_to_queue()
    assert panel.queue_list.count() == 2
    QTest.mouseClick(panel.buttons["start"], Qt.MouseButton.LeftButton)
    assert panel.queue_list.count() == 0
    wait_for(lambda: panel.worker is None, 2 * RUN_TIMEOUT_S, "both queued runs")
    runs, _ = _runs(tmp_path)
    assert [(r.status, r.n_samples, r.config["cycles"], r.campaign) for r in runs] == [
        ("completed", 10, 2, "queue test"),
        ("completed", 15, 3, "queue test"),
    ]
    wait_for(lambda: window.results.table.rowCount() == 2, RUN_TIMEOUT_S, "both runs in the results table")
    window.results.select_runs([r.id for r in runs])
    task = window.results.compare()
    wait_for(lambda: task.finished, 4 * RUN_TIMEOUT_S, "the comparison")
    comparison = tmp_path / "reports" / "compare_run1_run2.html"
    assert task.result == comparison and comparison.is_file()


def test_emergency_stop_cuts_the_running_settle_short_and_ends_the_campaign(window, tmp_path):
    window.robot_panel.speed_factor.setValue(10)  # a 600 s settle lasts 60 s: only the e-stop ends it in time
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / "iso9283_pose_quick.toml")
    panel.form.set_value("settle_s", "600")
    panel.start()
    wait_for(
        lambda: (
            panel.worker is not None
            and panel.worker.runner is not None
            and isinstance(panel.worker.runner.current_step, Settle)
        ),
        RUN_TIMEOUT_S,
        "the first settle",
    )
    QTest.mouseClick(window.estop, Qt.MouseButton.LeftButton)
    wait_for(lambda: panel.worker is None, RUN_TIMEOUT_S, "the stopped run to end")
    (run,), samples = _runs(tmp_path)
    assert (run.status, run.reason, run.n_samples) == ("aborted", "emergency stop", 0)
    assert run.settings["time_base"] == "simulated s (wall x speed factor 10)"
    assert "EMERGENCY STOP (software)" in window.log.toPlainText()
    assert f"run {run.id} aborted (0 samples): emergency stop" in window.log.toPlainText()


def _reading_pending(window):
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / "dissertation_pose.toml")
    panel.form.set_value("variant", "beta")
    panel.form.set_value("cycles", "2")
    panel.start()
    wait_for(lambda: window.calliper_dialog is not None, RUN_TIMEOUT_S, "the calliper dialog")
    return window.calliper_dialog.prompt


def test_closing_with_a_reading_pending_stops_first_then_asks_and_keeps_every_stored_sample(window, tmp_path):
    prompt = _reading_pending(window)
    dialog, worker = window.calliper_dialog, window.campaign_panel.worker
    wire = WireLog(worker.runner.rig.robot.controller)
    mark = wire.mark()
    window.close()
    # not closed: the emergency stop was pressed, the prompt withdrawn, and the window asks
    assert window.isVisible() and window.close_question.isVisible() and not dialog.isVisible()
    assert window.estop_latch.latched
    wait_for(lambda: wire.stopped_since(mark), RUN_TIMEOUT_S, "STOP on the wire")
    assert window.close_question.isVisible()  # the stop went out before anyone answered the question
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the stopped run to end")
    (run,), samples = _runs(tmp_path)
    assert (run.status, run.reason) == ("aborted", "emergency stop"), prompt.text
    assert [s.kind for s in samples[run.id]] == ["pose"]
    assert wire.moves_after_stop(mark) == []
    QTest.mouseClick(window.close_question.button(QMessageBox.StandardButton.Close), Qt.MouseButton.LeftButton)
    wait_for(lambda: not window.isVisible(), RUN_TIMEOUT_S, "the window to close")


def test_a_reading_cancelled_in_the_dialog_ends_the_run_resumable(window, tmp_path):
    prompt = _reading_pending(window)
    assert prompt.field == "b_deg"
    for _ in range(2):  # Cancel, then Cancel again to confirm that the campaign ends
        QTest.mouseClick(window.calliper_dialog.cancel_button, Qt.MouseButton.LeftButton)
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the run to end")
    (run,), samples = _runs(tmp_path)
    assert (run.status, run.reason) == (
        "aborted",
        f"prompt withdrawn by the operator: {prompt.text} (cancelled in the calliper dialog)",
    )
    assert [s.kind for s in samples[run.id]] == ["pose"]
    # resumed with the simulated calliper answering: nothing stored twice, every reading taken
    window.campaign_panel.simulated_calliper.setChecked(True)
    select_runs(window.results, [run.id])
    window.results.findChild(type(window.campaign_panel.buttons["start"]), "resultsResume").click()
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the resumed run to end")
    (resumed,), samples = _runs(tmp_path)
    steps = [s.step_index for s in samples[run.id]]
    assert resumed.status == "completed", (resumed.reason, window.log.toPlainText()[-1500:])
    assert len(steps) == len(set(steps)) == resumed.n_samples
    assert {s.kind for s in samples[run.id]} == {"pose", "tilt"} and samples[run.id][0].kind == "pose"


def test_a_rig_that_cannot_start_is_reported_and_nothing_is_stored(window, tmp_path):
    window.robot_panel.connection.setCurrentText("serial port")
    window.robot_panel.port.setText(str(tmp_path / "no-such-port"))
    window.campaign_panel.choose_file(EXAMPLES / "iso9283_pose_quick.toml")
    window.campaign_panel.start()
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the worker to give up")
    assert "serial port: protocol 'iso9283_pose' needs pose (add [mice] (pkm5)" in window.log.toPlainText()
    window.robot_panel.mouse_xy.setText(str(tmp_path / "xy"))
    window.robot_panel.mouse_xz.setText(str(tmp_path / "xz"))
    window.campaign_panel.start()
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the worker to give up")
    assert f"serial port: controller.port = '{tmp_path / 'no-such-port'}': cannot open it" in window.log.toPlainText()
    assert "--" not in window.log.toPlainText()  # no command-line flag names in the window
    assert _runs(tmp_path)[0] == []


def test_the_mice_and_their_mount_go_with_a_serial_port_only(window):
    panel = window.robot_panel
    panel.connection.setCurrentText("serial port")
    panel.port.setText("/dev/ttyUSB0")
    panel.mouse_xy.setText("/dev/input/xy")
    panel.mouse_xz.setText("/dev/input/xz")
    assert panel.mouse_xz_mount.isEnabled() and panel.rig_spec().request().mouse_xz_mount is None
    panel.mouse_xz_mount.setCurrentText("guided")
    request = panel.rig_spec().request()
    assert (request.port, request.mouse_xy, request.mouse_xz, request.mouse_xz_mount) == (
        "/dev/ttyUSB0",
        "/dev/input/xy",
        "/dev/input/xz",
        "guided",
    )
    panel.connection.setCurrentText("simulator")  # what the disabled fields hold is not sent to the simulator
    request = panel.rig_spec().request()
    assert not panel.mouse_xz_mount.isEnabled()
    assert (request.port, request.mouse_xy, request.mouse_xz, request.mouse_xz_mount) == (None, None, None, None)
