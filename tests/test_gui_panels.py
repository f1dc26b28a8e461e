"""The window's panels one at a time: calliper entry validation, the parameter form, the robot panel's
pre-flight-checked jog on the simulator, and the ``bench gui`` command."""

from __future__ import annotations

import pytest

pytest.importorskip("PySide6")

from gui_support import application, wait_for
from PySide6.QtCore import Qt
from PySide6.QtTest import QTest

from bench.cli import build_parser
from bench.errors import ConfigError
from bench.gui.calliper_dialog import CalliperDialog, parse_entry
from bench.gui.campaign_panel import EXAMPLES, format_duration
from bench.gui.parameter_form import ParameterForm, parse_field, show_value
from bench.gui.robot_panel import RobotPanel, check_target
from bench.protocols import Prompt, load_protocol
from bench.simulators.client import SimulatorClient

LEG = Prompt(
    "Load 1 kg: calliper length of leg 2",
    field="length_mm",
    unit="mm",
    minimum=150.0,
    maximum=280.0,
    commanded={"cmd_length_mm": 200.0},
)
TILT = Prompt("Point 1-1, repeat 1: calliper tilt alpha", field="a_deg", unit="deg", minimum=-45.0, maximum=45.0)


@pytest.mark.parametrize(
    ("prompt", "text", "value"),
    [
        (LEG, "200,12", 200.12),
        (LEG, " 200.5 mm ", 200.5),
        (LEG, '7.8750"', 200.025),
        (TILT, "-1,5", -1.5),
        (TILT, "12.25 deg", 12.25),
        (TILT, "+0.5", 0.5),
    ],
)
def test_entries_parse_as_the_terminal_prompt_parses_them(prompt, text, value):
    assert parse_entry(prompt, text) == (pytest.approx(value), "")


@pytest.mark.parametrize(
    ("prompt", "text", "message"),
    [
        (LEG, "12.3.4", "reading '12.3.4' is not a length"),
        (LEG, "100", "100 mm, expected 150 to 280 mm"),
        (TILT, "2 mm", "'2 mm' is not a reading in deg"),
        (TILT, "-46", "-46 deg, expected -45 to 45 deg"),
        (TILT, "", "is not a length"),
    ],
)
def test_bad_entries_are_refused_naming_the_value_and_the_range(prompt, text, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(")):
        parse_entry(prompt, text)


def test_a_length_far_from_the_commanded_one_needs_a_second_enter():
    application()
    dialog = CalliperDialog(LEG)
    readings: list[float] = []
    dialog.reading_entered.connect(readings.append)
    dialog.show()
    QTest.keyClicks(dialog.entry, "203.5")
    QTest.keyClick(dialog.entry, Qt.Key.Key_Return)
    assert readings == [] and "+3.500 mm from the expected 200 mm" in dialog.error.text()
    QTest.keyClick(dialog.entry, Qt.Key.Key_Return)
    assert readings == [203.5] and not dialog.isVisible()


def test_cancelling_the_dialog_reports_it():
    application()
    dialog = CalliperDialog(TILT)
    cancelled: list[bool] = []
    dialog.cancelled.connect(lambda: cancelled.append(True))
    dialog.show()
    QTest.keyClick(dialog.entry, Qt.Key.Key_Escape)  # the first Esc asks: the campaign would end
    assert cancelled == [] and dialog.isVisible() and "Cancelling ends the campaign" in dialog.error.text()
    QTest.keyClicks(dialog.entry, "1")  # typing again takes the cancellation back
    assert dialog.error.text() == "" and dialog.cancel_button.text() == "Cancel"
    QTest.keyClick(dialog.entry, Qt.Key.Key_Escape)
    QTest.keyClick(dialog.entry, Qt.Key.Key_Escape)
    assert cancelled == [True] and not dialog.isVisible()


def test_fields_show_and_read_toml_values():
    assert [show_value(v) for v in ([100.0, 50.0], "xy", None, {"P1": (1.0, 2.0)})] == [
        "[100, 50]",
        '"xy"',
        "",
        "{P1 = [1, 2]}",
    ]
    assert parse_field("[100, 50]") == [100, 50] and parse_field("50 mm") == "50 mm" and parse_field("3") == 3


def test_the_form_refuses_a_bad_value_with_the_parameters_message():
    application()
    form = ParameterForm()
    form.load(load_protocol(EXAMPLES / "iso9283_pose_quick.toml"), fixed={"robot": "pkm5"})
    seen: list[list[str]] = []
    form.changed.connect(lambda protocol, errors: seen.append(errors))
    form.set_value("cycles", "1")
    assert form.protocol is None
    assert seen[-1] == ["iso9283_pose_quick.toml: cycles = 1, expected an integer in [2, 100000]"]
    form.set_value("cycles", "4")
    form.set_value("settle_s", "250 ms")
    assert form.protocol is None and "settle_s" in seen[-1][0]
    form.set_value("settle_s", "0.25 s")
    assert form.protocol is not None and (form.protocol.cycles, form.protocol.settle_s) == (4, 0.25)
    assert not form.fields["robot"].isEnabled()


def test_durations_read_as_clock_times():
    assert [format_duration(s) for s in (0, 59.6, 61, 3600 * 2 + 61)] == ["0:00", "1:00", "1:01", "2:01:01"]


def test_jog_targets_are_checked_before_the_jog_button_allows_a_move():
    application()
    panel = RobotPanel()
    try:
        assert check_target("pkm5", (88.649, 0.0, 300.937, 0.0, 0.0))[0]
        reachable, text = check_target("pkm5", (400.0, 0.0, 300.0, 0.0, 0.0))
        assert not reachable and text.startswith("NOT reachable")
        assert check_target("delta4", (0.0, 0.0, -200.0))[0]
        assert check_target("delta4", (0.0, 0.0, 100.0)) == (False, "NOT reachable: above_knee (leg 1)")
        assert not panel.jog_button.isEnabled()  # nothing connected
        QTest.mouseClick(panel.connect_button, Qt.MouseButton.LeftButton)
        wait_for(lambda: panel.mover is not None and not panel.busy(), 30, "the simulator connection")
        assert panel.jog_button.isEnabled() and panel.status.text().startswith("connected")
        panel.set_target((400.0, 0.0, 300.0, 0.0, 0.0))
        assert not panel.jog_button.isEnabled() and panel.reach.text().startswith("NOT reachable")
        home = panel.target_boxes
        panel.set_home_target()
        home[0].setValue(home[0].value() + 5.0)  # 5 mm along x from home
        assert panel.jog_button.isEnabled()
        QTest.mouseClick(panel.jog_button, Qt.MouseButton.LeftButton)
        wait_for(lambda: panel.status.text().startswith("at "), 30, "the jog to end")
        true_pose = SimulatorClient(panel.mover.controller).true_pose()
        assert true_pose[0] == pytest.approx(88.649 + 5.0, abs=1.5)  # the simulated robot's own error model
        panel.emergency_stop()
        assert panel.status.text() == "EMERGENCY STOP latched: check the robot, then Reset e-stop"
        assert not panel.jog_button.isEnabled()
        wait_for(lambda: panel.mover.stop_latched, 30, "the stop thread's stop")
    finally:
        panel.wait_idle()
        panel.disconnect_robot()
    assert panel.mover is None and panel.status.text() == "disconnected"


def test_bench_gui_is_a_command():
    args = build_parser().parse_args(["gui", "--store", "x.db", "--reports", "out"])
    assert (args.group, args.store, args.reports) == ("gui", "x.db", "out")


def test_an_instruction_prompt_is_confirmed_with_enter():
    application()
    dialog = CalliperDialog(
        Prompt("Mount a payload of 2 kg on the end effector, then confirm", conditions={"load_kg": 2.0})
    )
    confirmed: list[bool] = []
    dialog.confirmed.connect(lambda: confirmed.append(True))
    dialog.show()
    assert dialog.windowTitle() == "Operator confirmation"
    QTest.keyClick(dialog, Qt.Key.Key_Return)
    assert confirmed == [True] and not dialog.isVisible()


def test_on_hardware_the_window_answers_every_prompt(tmp_path):
    """A rig without a simulated operator gets the window as its operator: readings and confirmations."""
    import threading

    from bench.gui.worker import CampaignWorker, RigSpec, WindowOperator

    application()
    worker = CampaignWorker(str(tmp_path / "bench.db"), [], RigSpec(port="/dev/null"))
    asked: list[Prompt] = []
    worker.prompt_requested.connect(lambda prompt: (asked.append(prompt), worker.answer(201.25)))
    operator = WindowOperator(worker)
    answers: list[float | None] = []
    thread = threading.Thread(target=lambda: answers.extend(operator.ask(p) for p in (LEG, Prompt("Confirm"))))
    thread.start()
    wait_for(lambda: not thread.is_alive(), 10, "the operator's answers")
    assert answers == [201.25, None] and [p.text for p in asked] == [LEG.text, "Confirm"]


def test_bench_gui_opens_the_window_on_the_store_and_returns_when_it_closes(tmp_path):
    from PySide6.QtCore import QTimer

    from bench.cli import main
    from bench.gui.app import MainWindow

    app = application()
    opened: list[str] = []

    def close_windows() -> None:
        for widget in app.topLevelWidgets():
            if isinstance(widget, MainWindow) and widget.isVisible():
                opened.append(widget.windowTitle())
                widget.close()

    hung: list[bool] = []
    QTimer.singleShot(300, close_windows)
    # never hang the suite: a loop that closing did not end (a window left open) is ended here, and fails the test
    QTimer.singleShot(10_000, lambda: (hung.append(True), app.quit()))
    assert main(["gui", "--store", str(tmp_path / "b.db"), "--reports", str(tmp_path / "r")]) == 0
    assert opened == [f"bench - {tmp_path / 'b.db'}"]
    assert not hung, "bench gui went on after its window closed"
    assert not (tmp_path / "b.db").exists()  # looking creates nothing: the first run creates the store
