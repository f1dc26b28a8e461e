"""The window's run queue, comparison of two runs, the emergency stop during a campaign, and closing the window
while a calliper reading is pending (simulated pkm5)."""

from __future__ import annotations

import os

os.environ["QT_QPA_PLATFORM"] = "offscreen"

import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, wait_for
from PySide6.QtCore import Qt
from PySide6.QtTest import QTest

from bench.gui.campaign_panel import EXAMPLES
from bench.store import Store


def _runs(tmp_path):
    with Store(tmp_path / "bench.db") as store:
        return store.runs(), {r.id: store.samples(r.id) for r in store.runs()}


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
        ("completed", 10, 2, "queue test"), ("completed", 15, 3, "queue test")]
    window.results.select_runs([r.id for r in runs])
    comparison = window.results.compare()
    assert comparison == tmp_path / "reports" / "compare_run1_run2.html" and comparison.is_file()


def test_emergency_stop_halts_the_campaign(window, tmp_path):
    window.robot_panel.speed_factor.setValue(60)
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / "iso9283_pose_quick.toml")
    panel.start()
    wait_for(lambda: panel.progress.value() >= 1, RUN_TIMEOUT_S, "a first stored sample")
    QTest.mouseClick(window.estop, Qt.MouseButton.LeftButton)
    wait_for(lambda: panel.worker is None, RUN_TIMEOUT_S, "the halted run to end")
    (run,), samples = _runs(tmp_path)
    assert (run.status, run.reason) == ("aborted", "halted by the operator")
    assert 1 <= run.n_samples < 15 and len(samples[run.id]) == run.n_samples
    assert "EMERGENCY STOP" in window.log.toPlainText()


def test_closing_with_a_reading_pending_keeps_every_stored_sample(window, tmp_path):
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / "dissertation_pose.toml")
    panel.form.set_value("variant", "beta")
    panel.form.set_value("cycles", "2")
    panel.start()
    wait_for(lambda: window.calliper_dialog is not None, RUN_TIMEOUT_S, "the calliper dialog")
    window.close()
    (run,), samples = _runs(tmp_path)
    # the runner has no way to withdraw a prompt: the cancelled reading ends the run as failed, with the reason
    assert run.status == "failed" and "PromptCancelled" in run.reason and "b_deg" in run.reason
    assert [s.kind for s in samples[run.id]] == ["pose"]


def test_a_rig_that_cannot_start_is_reported_and_nothing_is_stored(window, tmp_path):
    window.robot_panel.connection.setCurrentText("serial port")
    window.robot_panel.port.setText(str(tmp_path / "no-such-port"))
    window.campaign_panel.choose_file(EXAMPLES / "iso9283_pose_quick.toml")
    window.campaign_panel.start()
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the worker to give up")
    assert "--port: hardware runs support the pkm5 with --mouse-xy and --mouse-xz" in window.log.toPlainText()
    window.robot_panel.mouse_xy.setText(str(tmp_path / "xy"))
    window.robot_panel.mouse_xz.setText(str(tmp_path / "xz"))
    window.campaign_panel.start()
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the worker to give up")
    assert f"--port {tmp_path / 'no-such-port'}: cannot open it" in window.log.toPlainText()
    assert _runs(tmp_path)[0] == []
