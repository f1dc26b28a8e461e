"""Kinematic calibration from the desktop window, end to end on the simulated pkm5: a calibration run of a seeded
true geometry (``bench run examples/kinematic_calibration.toml``), "Identify from the selected run" clicked in the
window (``bench calibrate``'s function in a background task), then runs started from the window with the
calibration chosen in the panel, and with none.

Independent path: ``bench calibrate --json`` on a copy of the store taken before the click (the same run, the same
deterministic fit) for the parameters the window stored and shows."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import pytest

pytest.importorskip("PySide6")

from calibrated_pkm5 import example_with_cycles
from gui_support import RUN_TIMEOUT_S, select_runs, wait_for
from PySide6.QtCore import Qt, QTimer
from PySide6.QtTest import QTest

from bench.calibration.compensate import NEWEST, OFF
from bench.cli import main as bench_main
from bench.store import Store

SEED = 3  # true geometry (tests/test_kinematic_compensation.py)


def _bench(*args: str, store: Path) -> str:
    """``bench ARGS --store STORE`` through the console script's entry point (in this process); what it printed."""
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert bench_main([*args, "--store", str(store)]) == 0
    return printed.getvalue()


@pytest.fixture(scope="module")
def calibration_store(tmp_path_factory) -> tuple[Path, int]:
    """A store holding one calibration run of the seeded true geometry, and its id: run once for the module (each
    test works on its own copy)."""
    store = tmp_path_factory.mktemp("calibration") / "bench.db"
    said = _bench(
        "run",
        str(example_with_cycles("kinematic_calibration.toml", store.parent)),
        "--sim",
        "--true-geometry-seed",
        str(SEED),
        "--ideal",
        "--no-kinematic-calibration",
        "--no-progress",
        store=store,
    )
    return store, int(said.split()[-1])


@pytest.fixture
def calibration_run(calibration_store, tmp_path) -> int:
    """The test's ``bench.db`` (the window's store): a copy of the module's calibration store; the run's id."""
    store, run_id = calibration_store
    shutil.copy(store, tmp_path / "bench.db")
    return run_id


def _click_identify(window, run_id: int) -> int:
    """Select ``run_id`` in the results, click Identify, wait for the outcome; the timer ticks the event loop
    served meanwhile (the fit ran off the GUI thread)."""
    panel = window.calibration_panel
    select_runs(window.results, [run_id])
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(10)
    panel.last_dialog = None
    QTest.mouseClick(panel.identify_button, Qt.MouseButton.LeftButton)
    assert panel.busy() and not panel.identify_button.isEnabled()
    wait_for(lambda: panel.last_dialog is not None and not panel.busy(), 4 * RUN_TIMEOUT_S, "the identification")
    timer.stop()
    return len(ticks)


def _run_validation(window, choice) -> int:
    panel = window.campaign_panel
    window.calibration_panel.choose(choice)
    panel.choose_file(example_with_cycles("kinematic_validation.toml", Path(window.store_path).parent))
    assert panel.form.protocol is not None, panel.preflight.text()
    QTest.mouseClick(panel.buttons["start"], Qt.MouseButton.LeftButton)
    assert panel.worker is not None, window.log.toPlainText()
    wait_for(lambda: panel.worker is None, 2 * RUN_TIMEOUT_S, "the validation run")
    with Store(window.store_path, read_only=True) as store:
        return store.runs()[-1].id


@pytest.mark.slow
def test_identify_in_the_window_then_run_with_the_chosen_calibration_and_with_none(calibration_run, window, tmp_path):
    store_path, run_id = tmp_path / "bench.db", calibration_run
    shutil.copy(store_path, tmp_path / "copy.db")
    expected = json.loads(_bench("calibrate", str(run_id), "--json", store=tmp_path / "copy.db"))

    panel = window.calibration_panel
    panel.gain_box.setValue(10.0)  # bench calibrate --target-gain 10; the fit and uncertainty left at the defaults
    assert panel.identify_options() == {"fit": None, "uncertainty_mm": None, "target_gain": 10.0}
    ticks = _click_identify(window, run_id)
    assert ticks >= 3  # the window kept serving events while the fit ran in its background task
    assert panel.last_dialog.windowTitle() == "Calibration stored"
    with Store(store_path, read_only=True) as store:
        (record,) = [c for c in store.calibrations() if c.name == "pkm5_kinematics"]
    assert record.source_run_id == run_id and record.params["simulated"] is True
    assert record.id == expected["id"] and record.version == expected["version"] == 1
    assert sorted(record.params["parameters"]) == sorted(expected["parameters"])
    for name, entry in expected["parameters"].items():
        assert record.params["parameters"][name]["value"] == pytest.approx(entry["value"], abs=1e-9)
        assert record.params["parameters"][name]["uncertainty"] == pytest.approx(entry["uncertainty"], rel=1e-6)
    condition = expected["observability"]["condition_number"]
    assert record.params["campaign"]["plan"]["target_gain"] == 10.0 != expected["campaign"]["plan"]["target_gain"]
    shown = panel.result_text.toPlainText().splitlines()
    assert shown[0] == (
        f"pkm5_kinematics v1 (id {record.id}) from run {run_id}: 30 poses, "
        f"{len(expected['parameters'])} free parameters"
    )
    profiled = int(bool(expected["search"]["profile_widened"]))  # a line naming the parameters it widened
    assert shown[-6 - profiled].startswith("fit: maximum a posteriori, prior: manufacturing tolerances")  # the default
    assert shown[-5 - profiled].startswith(f"data part: condition number {condition:.3g} (the prior holds")
    assert shown[-4 - profiled] == (
        f"mean position error on the calibration poses (in-sample): before "
        f"{expected['ap_before_mm']:.3f} mm, after {expected['ap_after_mm']:.3f} mm"
    )
    assert shown[-3 - profiled].startswith("search: 8 starts from the prior")
    assert not profiled or shown[-3].startswith("profile likelihood: the objective rises slower than")
    assert shown[-2].startswith("robot scatter of one reading: ") and "instrument: 0.05 mm" in shown[-2]
    assert shown[-1].startswith("plan for 10x over the ")
    assert f"{shown[0]}" in window.log.toPlainText()

    # the new calibration is listed (read again in the background) and can be chosen for the window's runs
    box = panel.choice_box
    wait_for(lambda: box.findData(record.id) >= 0, RUN_TIMEOUT_S, "the calibration in the list")
    assert box.itemText(box.findData(record.id)) == f"pkm5_kinematics v1 (id {record.id}, from run {run_id}, simulated)"
    assert panel.choice() == NEWEST and [box.itemData(i) for i in range(box.count())] == [NEWEST, OFF, record.id]

    chosen = _run_validation(window, record.id)
    assert (
        f"kinematic calibration in force: pkm5_kinematics v1 (id {record.id} from run {run_id}; chosen)"
        in window.log.toPlainText()
    )
    none = _run_validation(window, OFF)
    assert (
        "kinematic calibration: none (--no-kinematic-calibration); commanding by the documented geometry"
        in window.log.toPlainText()
    )
    window.calibration_panel.choose(NEWEST)  # the default: what bench run does without a flag (its own test)
    assert window.rig_spec().request().kinematic_calibration == NEWEST
    with Store(store_path, read_only=True) as store:
        runs = {r.id: r for r in store.runs()}
    assert runs[chosen].status == runs[none].status == "completed"
    assert runs[chosen].settings["kinematic_calibration"] == {
        "id": record.id,
        "name": "pkm5_kinematics",
        "version": 1,
        "source_run_id": run_id,
        "reason": "chosen",
    }
    assert record.id in runs[chosen].calibration_ids and record.id not in runs[none].calibration_ids
    assert runs[none].settings["kinematic_calibration"] == {"id": None, "reason": "--no-kinematic-calibration"}


def test_a_run_without_measured_poses_is_refused_in_one_line(window, tmp_path):
    with Store(tmp_path / "bench.db") as store:
        run_id = store.start_run(protocol_name="kinematic_calibration", protocol_version="1", robot="pkm5", config={})
        store.add_sample(run_id, 0, values={"cmd_x_mm": 120.0}, kind="pose", pose="P1", cycle=1, t_s=0.0)
    # read at once: the store's poll (tests/test_gui_safety.py) would take up to a second
    QTest.mouseClick(window.results.buttons["refresh"], Qt.MouseButton.LeftButton)
    panel = window.calibration_panel
    assert panel.identify() is None  # nothing selected yet
    assert "Identify: select one run (a kinematic calibration run) in the Results tab" in window.log.toPlainText()
    _click_identify(window, run_id)
    text = (
        f"run {run_id}: no pose samples with measured x_mm, y_mm, z_mm; expected a run of commanded and measured poses"
    )
    assert panel.last_dialog.windowTitle() == f"Run {run_id} not identified"
    assert panel.last_dialog.text() == text and panel.status.text() == f"not identified: {text}"
    assert panel.identify_button.isEnabled() and panel.last_identified is None
    with Store(tmp_path / "bench.db", read_only=True) as store:
        assert [c for c in store.calibrations() if c.name == "pkm5_kinematics"] == []


def test_closing_the_window_during_an_identification_waits_for_it(calibration_run, tmp_path):
    from gui_support import application

    from bench.gui.app import MainWindow

    run_id = calibration_run
    application()
    main = MainWindow(tmp_path / "bench.db", tmp_path / "reports", open_files=False)
    main.show()
    select_runs(main.results, [run_id])
    QTest.mouseClick(main.calibration_panel.identify_button, Qt.MouseButton.LeftButton)
    assert main.calibration_panel.busy()
    main.close()  # returns once the identification has been stored
    assert main.calibration_panel.wait_idle(0.0)
    with Store(tmp_path / "bench.db", read_only=True) as store:
        assert [c.source_run_id for c in store.calibrations() if c.name == "pkm5_kinematics"] == [run_id]
