"""The desktop window end to end on the simulated pkm5: a campaign started from the window, live view, calliper
prompt answered in the dialog, pause then abort, closing mid-run and resuming, results browser, screenshot."""

from __future__ import annotations

import os

import numpy as np
import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, select_runs, serve_events, wait_for
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage
from PySide6.QtTest import QTest

from bench.gui.app import MainWindow
from bench.gui.campaign_panel import EXAMPLES
from bench.metrology.tables import analyze_poses, pose_table
from bench.protocols import RunState
from bench.store import Store, series_table, tidy_table


def _start(window: MainWindow, protocol_file: str, **values: str):
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / protocol_file)
    for name, text in values.items():
        panel.form.set_value(name, text)
    assert panel.form.protocol is not None, panel.preflight.text()
    QTest.mouseClick(panel.buttons["start"], Qt.MouseButton.LeftButton)
    assert panel.worker is not None, window.log.toPlainText()
    return panel.worker


def _wait_idle(window: MainWindow) -> None:
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the campaign to end")


def test_campaign_from_the_window_stores_every_sample_and_shows_it(window, tmp_path):
    _start(window, "iso9283_pose_quick.toml", cycles="2")
    _wait_idle(window)
    with Store(tmp_path / "bench.db") as store:
        (run,) = store.runs()
        table = tidy_table(store, run.id)
    assert run.status == "completed" and run.n_samples == 10  # 5 poses x 2 cycles x 1 velocity
    assert window.campaign_panel.progress.value() == 10
    assert "run 1 completed (10 samples)" in window.log.toPlainText()
    # live view: AP and RP per pose equal the report's (bench.metrology on the stored table), and an independent
    # computation of the barycentre and of RP_l = l̄ + 3 S_l in x, y, z
    shown = window.live_view.pose_statistics()
    assert sorted(shown) == ["P1", "P2", "P3", "P4", "P5"]
    report = {r.label: r for r in analyze_poses(pose_table(table), resamples=10)}
    for pose, rows in table.groupby("pose"):
        xyz = rows[["x_mm", "y_mm", "z_mm"]].to_numpy()
        barycentre = xyz.mean(axis=0) - rows[["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]].to_numpy()[0]
        distances = np.linalg.norm(xyz - xyz.mean(axis=0), axis=1)
        assert shown[pose]["APx_mm"] == pytest.approx(barycentre[0], abs=1e-9)
        assert shown[pose]["APy_mm"] == pytest.approx(barycentre[1], abs=1e-9)
        assert shown[pose]["AP_mm"] == pytest.approx(np.linalg.norm(barycentre), abs=1e-9)
        assert shown[pose]["RP_mm"] == pytest.approx(distances.mean() + 3 * distances.std(ddof=1), abs=1e-9)
        assert (shown[pose]["AP_mm"], shown[pose]["RP_mm"]) == (
            report[pose].accuracy.ap_mm,
            report[pose].repeatability.rp_mm,
        )
    # the stream's time axis is wall-clock time since the run started (a 2-cycle run takes seconds, not hours)
    window.live_view.redraw()
    assert window.live_view.stream_axes.get_xlabel() == "wall-clock time since the run started (s)"
    times = [t for series_times, _ in window.live_view.stream().values() for t in series_times]
    assert len(times) >= 10 and 0 <= min(times) <= max(times) < RUN_TIMEOUT_S
    # the status line says how the run ended, with its counts
    assert window.campaign_panel.eta.text() == f"idle - last: run {run.id} completed (10 / 10 samples)"
    # results browser lists the run with its status (read in the background)
    browser = window.results
    wait_for(
        lambda: browser.table.rowCount() == 1 and browser.table.item(0, 4).text() == "completed",
        RUN_TIMEOUT_S,
        "the results table",
    )
    assert [r.id for r in browser.records] == [run.id]
    assert [browser.table.item(0, c).text() for c in (0, 4, 5)] == [str(run.id), "completed", "10"]
    # the report of bench.reports, written from the browser in the background; a dialog names the file
    browser.select_runs([run.id])
    QTest.mouseClick(browser.buttons["report"], Qt.MouseButton.LeftButton)
    wait_for(lambda: browser.last_dialog is not None, 4 * RUN_TIMEOUT_S, "the report")
    report_html = tmp_path / "reports" / f"report_run{run.id}.html"
    assert browser.last_dialog.text() == str(report_html.resolve()) and report_html.is_file()
    assert (tmp_path / "reports" / f"report_run{run.id}.pdf").is_file()
    # a screenshot of the main window, not blank
    shot = tmp_path / "main_window.png"
    window.live_view.redraw()
    serve_events(50)
    assert window.grab().save(str(shot))
    image = QImage(str(shot))
    assert image.width() >= 1000 and image.height() >= 700
    colours = {image.pixel(x, y) for x in range(0, image.width(), 7) for y in range(0, image.height(), 7)}
    assert len(colours) > 50  # widgets, text and plotted points, not a uniform fill
    if os.environ.get("BENCH_GUI_SCREENSHOT"):
        window.grab().save(os.environ["BENCH_GUI_SCREENSHOT"])


def test_calliper_prompt_answered_in_the_dialog_then_pause_and_abort(window, tmp_path):
    worker = _start(window, "dissertation_pose.toml", variant="alpha", cycles="2", settle_s="0")
    wait_for(lambda: window.calliper_dialog is not None, RUN_TIMEOUT_S, "the calliper dialog")
    dialog = window.calliper_dialog
    assert "calliper tilt alpha" in dialog.prompt.text and dialog.prompt.field == "a_deg"
    for bad, message in (("abc", "not a reading in deg"), ("50", "expected -45 to 45 deg")):
        dialog.entry.setText(bad)
        QTest.keyClick(dialog.entry, Qt.Key.Key_Return)
        assert message in dialog.error.text() and dialog.isVisible()
    QTest.mouseClick(window.campaign_panel.buttons["pause"], Qt.MouseButton.LeftButton)
    dialog.entry.clear()
    QTest.keyClicks(dialog.entry, "-1,5 deg")  # a keyboard wedge types the reading, then Enter
    QTest.keyClick(dialog.entry, Qt.Key.Key_Return)
    wait_for(
        lambda: worker.runner is not None and worker.runner.state is RunState.PAUSED,
        RUN_TIMEOUT_S,
        "the run to pause at the checkpoint after the reading",
    )
    QTest.mouseClick(window.campaign_panel.buttons["abort"], Qt.MouseButton.LeftButton)
    _wait_idle(window)
    with Store(tmp_path / "bench.db") as store:
        (run,) = store.runs()
        samples = store.samples(run.id)
    assert (run.status, run.reason) == ("aborted", "aborted by the operator")
    assert [s.kind for s in samples] == ["pose", "tilt"]
    tilt = samples[1]
    assert tilt.values == {"a_deg": -1.5, "cmd_a_deg": dialog.prompt.commanded["cmd_a_deg"]}
    assert tilt.raw == {"field": "a_deg", "entered": -1.5, "typed": "-1,5 deg"} and (tilt.pose, tilt.cycle) == (
        dialog.prompt.pose,
        1,
    )


@pytest.mark.slow
def test_closing_mid_run_stops_the_robot_and_the_run_resumes_from_the_browser(window, tmp_path):
    # closing presses the emergency stop (issue 31): the run ends aborted at once, and Resume continues it
    window.robot_panel.speed_factor.setValue(120)
    _start(window, "iso9283_pose_quick.toml", cycles="3")
    wait_for(lambda: window.campaign_panel.progress.value() >= 2, RUN_TIMEOUT_S, "two stored samples")
    window.close()
    window.confirm_close()
    wait_for(lambda: not window.isVisible(), RUN_TIMEOUT_S, "the window to close after its stopped run")
    with Store(tmp_path / "bench.db") as store:
        (run,) = store.runs()
    assert (run.status, run.reason) == ("aborted", "emergency stop")
    assert 2 <= run.n_samples < 15  # every sample taken before the stop is stored
    assert run.n_samples == window.campaign_panel.progress.value()
    # a new window on the same store resumes the run from the results browser
    again = MainWindow(tmp_path / "bench.db", tmp_path / "reports", open_files=False)
    try:
        select_runs(again.results, [run.id])
        again.results.findChild(type(again.campaign_panel.buttons["start"]), "resultsResume").click()
        wait_for(lambda: again.campaign_panel.worker is None, RUN_TIMEOUT_S, "the resumed run to end")
        with Store(tmp_path / "bench.db") as store:
            resumed = store.run(run.id)
            steps = sorted(store.stored_steps(run.id))
        assert (resumed.status, resumed.n_samples) == ("completed", 15), resumed.reason
        assert again.campaign_panel.progress.value() == 15  # started at the stored count
        assert all(stats["n"] == 3 for stats in again.live_view.pose_statistics().values())
        assert sorted(again.live_view.samples) == steps  # every stored sample shown once, none twice
        assert len(steps) == len(set(steps)) == 15
    finally:
        again.close()


def test_stabilisation_run_shows_each_arrival_curve_as_stored_with_the_iso_bands(window, tmp_path):
    _start(window, "iso9283_stabilisation.toml", cycles="1", lead_s="0.1", hold_s="0.4")
    _wait_idle(window)
    with Store(tmp_path / "bench.db") as store:
        (run,) = store.runs()
        series = series_table(store, run.id)
    assert run.status == "completed" and run.n_samples == 5
    curves = window.live_view.arrival_curves()
    assert [label for label, _, _ in curves] == [f"{pose} cycle 1" for pose in ("P1", "P5", "P4", "P3", "P2")]
    for (_label, t_s, distance), (_, stored) in zip(curves, series.groupby("pose", sort=False), strict=True):
        # independently: the distance of every stored series point from the series' last point
        xyz = stored[["x_mm", "y_mm", "z_mm"]].to_numpy()
        np.testing.assert_allclose(t_s, stored["t_s"].to_numpy(), atol=1e-12)
        np.testing.assert_allclose(distance, np.sqrt(((xyz - xyz[-1]) ** 2).sum(axis=1)), atol=1e-12)
        assert distance[-1] == 0.0
        assert t_s[0] == pytest.approx(-0.1, abs=0.05) and t_s[-1] == pytest.approx(0.4, abs=0.05)
    window.live_view.redraw()
    axes = window.live_view.stream_axes
    assert axes.get_xlabel() == "time from the move's reported end (s)"
    bands = sorted(line.get_ydata()[0] for line in axes.get_lines() if line.get_linestyle() == "--")
    assert bands == [0.1, 0.5, 1.0]


def test_closing_the_window_ends_the_live_view_render_thread(window):
    """A render thread left running at exit handed a last picture to a process pool the interpreter was shutting
    down ('cannot schedule new futures after interpreter shutdown' in the log): closing the window ends it."""
    renderer_thread = window.live_view._renderer.thread
    assert renderer_thread.is_alive()
    window.close()
    renderer_thread.join(timeout=10)
    assert not renderer_thread.is_alive()
