"""The desktop window as an operator uses it, with real widget events (QTest clicks and key presses) on the
simulated pkm5: the software emergency stop during an open calliper prompt (button and F12), Report during a run,
the run buttons following the runner's state machine, the results table following the store, the calliper
dialog's numbering, labels, cancel confirmation and layout, ``bench gui`` without a display, and a screenshot of
each panel (saved under ``$BENCH_GUI_ARTEFACTS``, else the test's temporary folder)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, application, real_display, select_runs, serve_events, wait_for
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QImage
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication, QLabel

from bench.gui import offload
from bench.gui.calliper_dialog import CalliperDialog
from bench.gui.campaign_panel import EXAMPLES, enabled_actions
from bench.protocols import Prompt, RunState, Settle
from bench.store import Store

#: dissertation_pose: 15 points (000 §8.6.3, Table 8-2), one tilt reading per point and cycle in the angle variants.
POINTS = 15
LEG = Prompt(
    "Load 1 kg: calliper length of leg 2",
    field="length_mm",
    unit="mm",
    minimum=150.0,
    maximum=280.0,
    commanded={"cmd_length_mm": 200.0},
)


def _click(widget) -> None:
    QTest.mouseClick(widget, Qt.MouseButton.LeftButton)


def _start(window, protocol_file: str, **values: str):
    panel = window.campaign_panel
    panel.choose_file(EXAMPLES / protocol_file)
    for name, text in values.items():
        panel.form.set_value(name, text)
    assert panel.form.protocol is not None, panel.preflight.text()
    _click(panel.buttons["start"])
    assert panel.worker is not None, window.log.toPlainText()
    return panel.worker


def _wait_idle(window) -> None:
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the campaign to end")


def _runs(tmp_path):
    with Store(tmp_path / "bench.db") as store:
        return [(r, store.samples(r.id)) for r in store.runs()]


def _reading_pending(window):
    worker = _start(window, "dissertation_pose.toml", variant="alpha", cycles="2", settle_s="0")
    wait_for(
        lambda: window.calliper_dialog is not None or window.campaign_panel.worker is None,
        RUN_TIMEOUT_S,
        "the calliper dialog",
    )
    assert window.calliper_dialog is not None, f"the run ended first: {window.log.toPlainText()}"
    return window.calliper_dialog, worker


@pytest.mark.parametrize("how", ["button", "F12 in the dialog"])
def test_the_emergency_stop_acts_while_a_prompt_is_open_and_withdraws_it(window, tmp_path, how):
    dialog, worker = _reading_pending(window)
    controller = worker.runner.rig.robot.controller
    assert dialog.isVisible() and not dialog.isModal() and not controller._stop_latched
    assert window.estop.isEnabled() and window.estop.text() == "EMERGENCY STOP (software, F12)"
    if how == "button":
        _click(window.estop)  # the main window is not blocked by the prompt
    else:
        # a key reaches an application only through its focused window: Qt delivers an application-wide shortcut only
        # while one of the application's windows is active, which the X server grants asynchronously after a show
        # (under load it came after the key once, and F12 went to the entry as a plain key)
        wait_for(
            lambda: QApplication.activeWindow() is not None,
            RUN_TIMEOUT_S,
            "a window of the application to have the keyboard focus",
        )
        QTest.keyClick(dialog.entry, Qt.Key.Key_F12)  # focus in the dialog: the shortcut is application-wide
    # pressed and withdrawn within the click's own handling; the stop thread takes the press to the wire
    assert window.estop_latch.latched and not dialog.isVisible()
    wait_for(lambda: controller._stop_latched, RUN_TIMEOUT_S, "the stop thread's emergency stop")
    assert worker.runner is None or worker.runner.state in (RunState.HALTING, RunState.FINISHED)
    assert window.calliper_dialog is None
    _wait_idle(window)
    ((run, samples),) = _runs(tmp_path)
    assert (run.status, run.reason) == ("aborted", "emergency stop")
    assert [s.kind for s in samples] == ["pose"]  # the pending reading was withdrawn, never invented
    # a dialog tells how the run ended and how to continue it
    assert window.last_dialog is not None and window.last_dialog.isVisible()
    assert f"bench resume {run.id} --store {tmp_path / 'bench.db'}" in window.last_dialog.text()
    assert (
        window.campaign_panel.eta.text() == f"idle - last: run {run.id} aborted (1 / {2 * POINTS * 2} "
        "samples): emergency stop"
    )


def test_readings_are_numbered_and_a_cancel_asks_before_it_ends_the_campaign(window, tmp_path):
    dialog, worker = _reading_pending(window)
    assert dialog.number.text() == f"Reading 1 of {POINTS * 2}"
    assert "Cancel" == dialog.cancel_button.text()
    QTest.keyClicks(dialog.entry, "0,5")  # decimal comma
    QTest.keyClick(dialog.entry, Qt.Key.Key_Return)
    wait_for(lambda: window.calliper_dialog not in (None, dialog), RUN_TIMEOUT_S, "the second reading")
    second = window.calliper_dialog
    assert second.number.text() == f"Reading 2 of {POINTS * 2}"
    QTest.keyClick(second.entry, Qt.Key.Key_Escape)
    serve_events(100)
    assert second.isVisible() and worker.runner.state is RunState.RUNNING  # asked, not yet cancelled
    _click(second.cancel_button)
    _wait_idle(window)
    ((run, samples),) = _runs(tmp_path)
    assert run.status == "aborted" and run.reason.endswith("(cancelled in the calliper dialog)")
    assert [s.values.get("a_deg") for s in samples if s.kind == "tilt"] == [0.5]
    assert window.last_dialog is not None and f"bench resume {run.id}" in window.last_dialog.text()


def test_the_calliper_dialog_speaks_to_the_operator_and_keeps_its_layout():
    application()
    dialog = CalliperDialog(LEG, number=(3, 141))
    readings: list[float] = []
    dialog.reading_entered.connect(readings.append)
    dialog.show()
    serve_events(50)
    texts = [label.text() for label in dialog.findChildren(QLabel)]
    assert "Reading 3 of 141" in texts and "length in mm" in texts and "150 to 280 mm" in texts
    assert "200 mm: the value the robot was commanded to (a reading more than 2 mm away is asked again)" in texts
    assert not any("length_mm" in text for text in texts)  # no internal field names
    size = dialog.size()
    QTest.keyClicks(dialog.entry, "12.3.4")
    QTest.keyClick(dialog.entry, Qt.Key.Key_Return)
    serve_events(50)
    assert "is not a length" in dialog.error.text() and dialog.size() == size  # room kept for the message
    dialog.entry.clear()
    QTest.keyClicks(dialog.entry, "200,25")
    QTest.keyClick(dialog.entry, Qt.Key.Key_Enter)  # the keypad's Enter submits too
    assert readings == [200.25] and not dialog.isVisible()


@pytest.mark.parametrize(
    ("state", "legal"),
    [
        (None, {"start"}),
        ("starting", set()),
        ("idle", set()),
        ("running", {"pause", "stop", "abort"}),
        ("pause requested", {"stop", "abort"}),
        ("paused", {"resume", "stop", "abort"}),
        ("stopping", {"abort"}),
        ("aborting", set()),
        ("halting", set()),
        ("finished", set()),
    ],
)
def test_the_legal_buttons_are_the_runners_transitions(state, legal):
    assert enabled_actions(state) == legal


def test_the_buttons_follow_the_run_and_the_form_locks(window, tmp_path):
    panel = window.campaign_panel
    window.robot_panel.speed_factor.setValue(100)  # a cycle (5 samples) lasts a second or two: time to click
    enabled = lambda: {action for action, button in panel.buttons.items() if button.isEnabled()}  # noqa: E731
    assert enabled() == {"start"} and panel.form.isEnabled()
    worker = _start(window, "iso9283_pose_quick.toml", cycles="4")
    wait_for(lambda: panel.state == "running", RUN_TIMEOUT_S, "the run")
    assert enabled() == {"pause", "stop", "abort"}
    assert not any(w.isEnabled() for w in (panel.form, panel.files, panel.add_button, panel.campaign))
    _click(panel.buttons["pause"])
    assert enabled() == {"stop", "abort"}  # a pause is pending until the next checkpoint
    wait_for(lambda: panel.state == "paused", RUN_TIMEOUT_S, "the pause at a checkpoint")
    assert enabled() == {"resume", "stop", "abort"}
    _click(panel.buttons["resume"])
    assert enabled() == {"pause", "stop", "abort"} and worker.runner.state is RunState.RUNNING
    _click(panel.buttons["abort"])
    assert enabled() == set()
    _wait_idle(window)
    assert enabled() == {"start"} and panel.form.isEnabled()
    ((run, samples),) = _runs(tmp_path)
    assert run.status == "aborted" and len(samples) < 20
    assert (
        panel.eta.text() == f"idle - last: run {run.id} aborted ({len(samples)} / 20 samples): aborted by the operator"
    )
    assert window.last_dialog is None  # the operator ended it: no failure dialog


def test_the_results_table_follows_runs_made_from_outside_the_window(window, tmp_path):
    scan = window.results.refresh()  # no store yet: an empty list, and no file made where none was asked for
    wait_for(lambda: window.results._scan is None, 5, "the scan of a missing store")
    assert scan is not None and window.results.table.rowCount() == 0 and list(tmp_path.glob("bench.db*")) == []
    with Store(tmp_path / "bench.db") as store:  # as bench run does, in another process
        run_id = store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config={})
        wait_for(lambda: window.results.table.rowCount() == 1, 5, "the table to list the new run")
        assert [window.results.table.item(0, c).text() for c in (0, 4)] == [str(run_id), "running"]
    with Store(tmp_path / "bench.db") as store:
        store.set_status(run_id, "failed", reason="rig fault")
    wait_for(lambda: window.results.table.item(0, 4).text() == "failed", 5, "the new status")
    assert window.results.table.item(0, 7).text() == "rig fault"


_OWNER = """
import sys, time
from bench.store import Store
store = Store(sys.argv[1])
store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config={})
print("owned", flush=True)
sys.stdin.read()  # owns the run until killed
"""


def test_the_results_table_shows_a_run_whose_owner_was_killed_as_interrupted(window, tmp_path):
    owner = subprocess.Popen(
        [sys.executable, "-c", _OWNER, str(tmp_path / "bench.db")],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert owner.stdout.readline() == "owned\n"
        wait_for(lambda: window.results.table.rowCount() == 1, 5, "the table to list the new run")
        wait_for(lambda: window.results.table.item(0, 4).text() == "running", 5, "the running run")
    finally:
        owner.kill()
        owner.communicate(timeout=10)
    wait_for(lambda: window.results.table.item(0, 4).text() == "interrupted", 5, "the killed owner to show")
    assert window.results.table.item(0, 7).text().endswith("is gone; next: bench resume 1")


def test_report_during_a_run_leaves_the_window_responsive(window, tmp_path):
    _start(window, "iso9283_pose_quick.toml", cycles="2")
    _wait_idle(window)
    window.robot_panel.speed_factor.setValue(20)  # a 600 s settle lasts 30 s: the run goes on during the report
    worker = _start(window, "iso9283_pose_quick.toml", settle_s="600")
    wait_for(
        lambda: worker.runner is not None and isinstance(worker.runner.current_step, Settle),
        RUN_TIMEOUT_S,
        "the long settle",
    )
    select_runs(window.results, [1])
    report = tmp_path / "reports" / "report_run1.html"
    answered: list[bool] = []  # per event-loop probe: whether the report was still being written when it ran

    def probe() -> None:  # posted now, answered when the loop is free
        QTimer.singleShot(0, lambda: answered.append(not report.exists()))

    prober = QTimer()
    prober.timeout.connect(probe)
    prober.start(25)
    _click(window.results.buttons["report"])
    assert not report.exists()  # the click came back before the report was written: it is made elsewhere
    wait_for(lambda: window.results.last_dialog is not None, 4 * RUN_TIMEOUT_S, "the report")
    prober.stop()
    # the loop kept answering while the report was made, and the report was made in another process (a thread
    # would hold the interpreter lock for seconds of matplotlib; bench.gui.offload says why). How fast the loop
    # answers is a figure for a benchmark, not for a test on a loaded machine.
    assert answered.count(True) >= 4, answered
    (report_process,) = offload._reports.executor._processes.values()
    assert report_process.pid != os.getpid()
    assert worker.runner.state is RunState.RUNNING  # the run went on meanwhile
    assert (tmp_path / "reports" / "report_run1.html").is_file()
    _click(window.estop)
    _wait_idle(window)


def test_bench_gui_without_a_display_says_so_in_one_line(tmp_path):
    environ = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    environ["PYTHONPATH"] = str(Path(__file__).resolve().parents[1])
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from bench.cli import main; sys.exit(main())",
            "gui",
            "--store",
            str(tmp_path / "b.db"),
        ],
        env=environ,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "bench: error: bench gui: no display (DISPLAY and WAYLAND_DISPLAY are not set); run it in a desktop "
        "session, over ssh -X, or under xvfb-run"
    ]


def _non_blank(path: Path, min_width: int, min_height: int) -> None:
    image = QImage(str(path))
    assert image.width() >= min_width and image.height() >= min_height, (path, image.width(), image.height())
    pixels = [image.pixel(x, y) for x in range(0, image.width(), 5) for y in range(0, image.height(), 5)]
    _, counts = np.unique(pixels, return_counts=True)
    assert len(counts) > 20 and counts.max() < 0.97 * len(pixels), path  # text and widgets, not a uniform fill


def test_a_screenshot_of_each_panel(window, tmp_path):
    out = Path(os.environ.get("BENCH_GUI_ARTEFACTS") or tmp_path / "screenshots")
    out.mkdir(parents=True, exist_ok=True)
    window.resize(1400, 860)
    _start(window, "iso9283_pose_quick.toml", cycles="3")
    _wait_idle(window)
    window.live_view.redraw()
    serve_events(100)
    shots = {
        "window": window,
        "robot_panel": window.robot_panel,
        "campaign_panel": window.campaign_panel,
        "live_view": window.live_view,
    }
    for name, widget in shots.items():
        path = out / f"gui_{name}.png"
        assert widget.grab().save(str(path))
        _non_blank(path, 250, 150)
    dialog, _ = _reading_pending(window)
    dialog.entry.setText("50")
    QTest.keyClick(dialog.entry, Qt.Key.Key_Return)  # a validation message in the picture
    serve_events(100)
    path = out / "gui_calliper_dialog.png"
    assert dialog.grab().save(str(path))
    _non_blank(path, 250, 150)
    _click(window.estop)
    _wait_idle(window)
    window.tabs.setCurrentWidget(window.results)
    wait_for(lambda: window.results.table.rowCount() == 2, RUN_TIMEOUT_S, "both runs in the results table")
    serve_events(50)
    path = out / "gui_results.png"
    assert window.results.grab().save(str(path))
    _non_blank(path, 250, 150)
    print(f"screenshots in {out} ({'X server' if real_display() else 'offscreen'})")


def test_export_writes_the_default_kind_of_bench_export(window, tmp_path):
    with Store(tmp_path / "bench.db") as store:  # a run of tilt readings only (no pose samples)
        run_id = store.start_run(protocol_name="tilt", protocol_version="1", robot="pkm5", config={})
        for index, reading in enumerate((-1.5, 0.25)):
            store.add_sample(
                run_id,
                index,
                values={"a_deg": reading, "cmd_a_deg": 0.0},
                kind="tilt",
                pose="P1",
                cycle=index + 1,
                t_s=float(index),
                raw={"field": "a_deg", "entered": reading},
            )
    _click(window.results.buttons["refresh"])  # at once: the store's poll (its own test) would take up to a second
    select_runs(window.results, [run_id])
    _click(window.results.buttons["export"])
    wait_for(lambda: window.results.last_dialog is not None, RUN_TIMEOUT_S, "the export")
    path = tmp_path / "reports" / f"run-{run_id}-tilt.csv"
    assert window.results.last_dialog.text() == str(path.resolve())
    table = pd.read_csv(path)
    assert table["a_deg"].tolist() == [-1.5, 0.25] and table["pose"].tolist() == ["P1", "P1"]


def test_the_stream_draws_measurements_not_the_conditions_of_a_capture():
    from bench.gui.live_view import LiveView

    application()
    view = LiveView()
    view.clear("run 1", started_s=1000.0)
    arrival = {
        "kind": "arrival",
        "pose": "P1",
        "cycle": 1,
        "t_s": 5e4,
        "wall_s": 1004.5,
        "values": {"x_mm": 110.25, "cmd_x_mm": 110.0, "lead_s": 0.2, "hold_s": 2.0, "velocity_pct": 100.0},
    }
    assert view.add_sample(dict(arrival, step_index=7)) and not view.add_sample(dict(arrival, step_index=7))
    assert view.stream() == {"x_mm - cmd": ([4.5], [pytest.approx(0.25)])}  # wall-clock s since the start


def test_the_live_figures_are_per_pose_and_velocity_as_in_the_report():
    from bench.gui.live_view import LiveView
    from bench.metrology.tables import analyze_poses, pose_table

    application()
    rng = np.random.default_rng(19)
    view = LiveView()
    view.clear("run 1", started_s=0.0)
    rows = []
    for index, (velocity, cycle) in enumerate((v, c) for v in (50.0, 100.0) for c in (1, 2, 3)):
        offset = 0.1 if velocity == 50.0 else 0.9  # the faster visits land further off: pooled, AP would mix them
        attained = np.array([110.0, 0.0, 320.0]) + offset + rng.normal(0.0, 0.05, 3)
        values = {
            "x_mm": attained[0],
            "y_mm": attained[1],
            "z_mm": attained[2],
            "cmd_x_mm": 110.0,
            "cmd_y_mm": 0.0,
            "cmd_z_mm": 320.0,
            "velocity_pct": velocity,
            "load_kg": 0.0,
        }
        view.add_sample(
            {
                "step_index": index,
                "kind": "pose",
                "pose": "P1",
                "cycle": cycle,
                "t_s": float(index),
                "wall_s": float(index),
                "values": values,
            }
        )
        rows.append({"pose": "P1", "cycle": cycle, **values})
    view.add_sample(
        {
            "step_index": 0,
            "kind": "pose",
            "pose": "P1",
            "cycle": 1,
            "t_s": 0.0,
            "wall_s": 0.0,
            "values": rows[0] | {"x_mm": 999.0},
        }
    )  # the same step again (a resume): ignored
    shown = view.pose_statistics()
    report = {r.label: r for r in analyze_poses(pose_table(pd.DataFrame(rows)), resamples=10)}
    assert sorted(shown) == sorted(report) == ["P1 (velocity_pct=100)", "P1 (velocity_pct=50)"]
    for label, result in report.items():
        assert shown[label]["n"] == 3
        assert (shown[label]["AP_mm"], shown[label]["RP_mm"]) == (result.accuracy.ap_mm, result.repeatability.rp_mm)
    assert shown["P1 (velocity_pct=100)"]["AP_mm"] == pytest.approx(0.9 * np.sqrt(3), abs=0.2)


def _pose_sample(index: int) -> dict:
    values = {"x_mm": 110.1, "y_mm": 0.1 * index, "z_mm": 320.0, "cmd_x_mm": 110.0, "cmd_y_mm": 0.0, "cmd_z_mm": 320.0}
    return {
        "step_index": index,
        "kind": "pose",
        "pose": "P1",
        "cycle": index + 1,
        "t_s": float(index),
        "wall_s": float(index),
        "values": values,
    }


def test_the_live_view_draws_in_its_render_process_and_only_while_it_can_be_seen():
    from bench.gui import live_view
    from bench.gui.live_view import LiveView

    application()
    view = LiveView()
    view.resize(700, 500)
    view.clear("run 1", started_s=0.0)
    view.add_sample(_pose_sample(0))
    view.show()
    wait_for(lambda: view.renders == 1, RUN_TIMEOUT_S, "the first picture")
    assert "P1: n=1 " in view.summary.text() and view.picture.pixmap().width() > 0
    (render_process,) = live_view._render_process.executor._processes.values()
    assert render_process.pid != os.getpid()  # drawn in the render process, not under the window's lock
    view.hide()  # another tab
    view.add_sample(_pose_sample(1))
    view._timed_redraw()  # the timer's turn (it would come after the pause the first draw asks for)
    serve_events(50)
    assert view.renders == 1 and "P1: n=1 " in view.summary.text()  # collected only
    view.show()
    wait_for(lambda: view.renders == 2, RUN_TIMEOUT_S, "the picture once shown")
    assert "P1: n=2 " in view.summary.text()
    view.close()
