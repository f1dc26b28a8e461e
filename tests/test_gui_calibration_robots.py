"""The calibration box's "In force" chooser lists the calibrations of the robot chosen in the robot panel: the
pkm5's ``pkm5_kinematics`` versions, the delta4's ``delta4_kinematics`` versions, none for a robot without a
calibration model; switching the robot lists the other robot's, and a runs' choice follows (bench.gui)."""

from __future__ import annotations

import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, wait_for

from bench.calibration.compensate import NEWEST, OFF
from bench.store import Store


def _listed(panel) -> list:
    box = panel.choice_box
    return [box.itemData(i) for i in range(box.count())]


def test_the_chooser_lists_the_chosen_robots_own_calibrations(window):
    with Store(window.store_path) as store:
        pkm5 = store.add_calibration("pkm5_kinematics", {"robot": "pkm5", "parameters": {}})
        delta4 = [
            store.add_calibration(
                "delta4_kinematics", {"robot": "delta4", "parameters": {}, "simulated": True}, source_run_id=None
            )
            for _ in range(2)
        ]
    panel, robots = window.calibration_panel, window.robot_panel.robot
    robots.setCurrentText("pkm5")
    panel.refresh()
    wait_for(lambda: _listed(panel) == [NEWEST, OFF, pkm5.id], RUN_TIMEOUT_S, "the pkm5 calibrations")

    robots.setCurrentText("delta4")
    wait_for(
        lambda: _listed(panel) == [NEWEST, OFF, delta4[1].id, delta4[0].id],
        RUN_TIMEOUT_S,
        "the delta4 calibrations, newest first",
    )
    box = panel.choice_box
    assert box.itemText(2) == f"delta4_kinematics v2 (id {delta4[1].id}, from run None, simulated)"
    panel.choose(delta4[0].id)
    assert window.rig_spec().request().kinematic_calibration == delta4[0].id and window.rig_spec().robot == "delta4"

    robots.setCurrentText("pkm5")  # the delta4 calibration is not the pkm5's: back to the newest, said in the log
    wait_for(lambda: _listed(panel) == [NEWEST, OFF, pkm5.id], RUN_TIMEOUT_S, "the pkm5 calibrations again")
    assert panel.choice() == NEWEST
    assert (
        f"kinematic calibration id {delta4[0].id} is not a stored calibration of the pkm5: newest chosen"
        in window.log.toPlainText()
    )
    others = [name for name in (robots.itemText(i) for i in range(robots.count())) if name not in ("pkm5", "delta4")]
    if others:  # a robot without a calibration model (prus3): newest / none only
        robots.setCurrentText(others[0])
        wait_for(lambda: _listed(panel) == [NEWEST, OFF], RUN_TIMEOUT_S, f"no calibration for the {others[0]}")
